"""The firmware's calibration file: what the navigation computer knows about its sensors.

A real team measures its camera (intrinsics, distortion, boresight to the body, polarizer angles), its compass
units and its magnetometer once, on the bench, and loads the result into the DSP. The firmware reads only this
file -- never the world's truth (docs/architecture.md, the independence rule); the virtual DSP writes the file
that a run uses into the run directory (``calibration.json``), and a user may hand in their own. Every field has
the nominal design as its default, so ``Calibration()`` is an uncalibrated unit.

Format (JSON, ``docs/calibration.md``): ``{"format": "psns-hil-calibration", "version": 1, "camera": {...},
"compass": {...}, "magnetometer": {...}}``. Angles in degrees, lengths in metres or pixels as named.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from typing import Any

from .errors import FirmwareError

#: the IMX250MZR's nominal micro-polarizer channel angles (deg from image +x towards +y): the layout the camera's
#: on-chip Stokes processing assumes and the calibration's measured angles deviate from
NOMINAL_POLARIZER_DEG: tuple[float, float, float, float] = (0.0, 45.0, 90.0, 135.0)

__all__ = ["MAX_CALIBRATION_BYTES", "Calibration", "CalibrationError", "CameraCalibration", "CompassCalibration",
           "MagnetometerCalibration", "calibration_from_data", "load_calibration", "save_calibration"]

FORMAT = "psns-hil-calibration"
VERSION = 1
#: largest calibration file read (bytes): a full one is about 2 KB; a larger file is refused after one bounded read
MAX_CALIBRATION_BYTES = 1 << 20


class CalibrationError(FirmwareError):
    """A calibration file that cannot be used (malformed, out of range, wrong format)."""


@dataclass(frozen=True)
class CameraCalibration:
    """The polarization camera as calibrated (conventions: docs/architecture.md, "Conventions").

    ``cx_px``/``cy_px`` principal point (1-based pixels; None: the sensor centre); ``k1``/``k2`` radial
    distortion (Brown on ``tan(theta)`` for pinhole, Kannala-Brandt on ``theta`` for fisheye); ``exit_pupil_m``
    exit pupil to image plane (None: a thin lens, chief-ray angle = field angle); ``boresight_rotvec_deg`` the
    camera-to-body rotation ``C_c^b`` as a rotation vector (deg); ``polarizer_deg`` the measured orientations of
    the four micro-polarizer channels; ``extinction_ratio`` their measured mean.
    """

    projection: str = "pinhole"
    nx: int = 2448
    ny: int = 2048
    pixel_m: float = 3.45e-6
    focal_m: float = 4.0e-3
    cx_px: float | None = None
    cy_px: float | None = None
    k1: float = 0.0
    k2: float = 0.0
    exit_pupil_m: float | None = None
    boresight_rotvec_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)
    polarizer_deg: tuple[float, float, float, float] = NOMINAL_POLARIZER_DEG
    extinction_ratio: float = 300.0


@dataclass(frozen=True)
class CompassCalibration:
    """Installation angles of the compass units (rotation vectors about each unit's axes, deg; empty: nominal)."""

    unit_installation_deg: tuple[tuple[float, float, float], ...] = ()


@dataclass(frozen=True)
class MagnetometerCalibration:
    """Hard iron (nT, body axes) and soft iron (3x3, row-major) of the magnetometer as calibrated."""

    hard_iron_nt: tuple[float, float, float] = (0.0, 0.0, 0.0)
    soft_iron: tuple[float, ...] = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0)


@dataclass(frozen=True)
class Calibration:
    camera: CameraCalibration = field(default_factory=CameraCalibration)
    compass: CompassCalibration = field(default_factory=CompassCalibration)
    magnetometer: MagnetometerCalibration = field(default_factory=MagnetometerCalibration)

    def to_dict(self) -> dict[str, Any]:
        return {"format": FORMAT, "version": VERSION, **asdict(self)}

    @classmethod
    def from_dict(cls, data: Any) -> Calibration:
        if not isinstance(data, dict) or data.get("format") != FORMAT:
            raise CalibrationError(f"not a calibration file (format must be {FORMAT!r})")
        if data.get("version") != VERSION:
            raise CalibrationError(f"calibration version {data.get('version')!r} not supported (expected {VERSION})")
        extra = set(data) - {"format", "version", "camera", "compass", "magnetometer"}
        if extra:
            raise CalibrationError(f"unknown calibration sections: {sorted(extra)}")
        cal = cls(camera=_section(CameraCalibration, data.get("camera", {}), "camera"),
                  compass=_section(CompassCalibration, data.get("compass", {}), "compass"),
                  magnetometer=_section(MagnetometerCalibration, data.get("magnetometer", {}), "magnetometer"))
        _check(cal)
        return cal


def _tuple(v: Any) -> Any:
    return tuple(_tuple(x) for x in v) if isinstance(v, list | tuple) else v


def _section(cls: Any, data: Any, name: str) -> Any:
    if not isinstance(data, dict):
        raise CalibrationError(f"{name}: must be an object")
    known = {f.name for f in fields(cls)}
    extra = set(data) - known
    if extra:
        raise CalibrationError(f"{name}: unknown fields {sorted(extra)}")
    try:
        return cls(**{k: _tuple(v) for k, v in data.items()})
    except TypeError as exc:
        raise CalibrationError(f"{name}: {exc}") from exc


def _num(name: str, v: Any, lo: float, hi: float, none_ok: bool = False) -> None:
    if v is None and none_ok:
        return
    if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v) or not lo <= v <= hi:
        raise CalibrationError(f"{name}: {v!r} is not a number in [{lo}, {hi}]")


def _vec(name: str, v: Any, n: int, lo: float, hi: float) -> None:
    if not isinstance(v, tuple) or len(v) != n:
        raise CalibrationError(f"{name}: needs {n} numbers")
    for i, x in enumerate(v):
        _num(f"{name}[{i}]", x, lo, hi)


def _check(cal: Calibration) -> None:
    c = cal.camera
    if c.projection not in ("pinhole", "fisheye"):
        raise CalibrationError(f"camera.projection: {c.projection!r} is not pinhole or fisheye")
    _num("camera.nx", c.nx, 2, 20000)
    _num("camera.ny", c.ny, 2, 20000)
    _num("camera.pixel_m", c.pixel_m, 1e-7, 1e-4)
    _num("camera.focal_m", c.focal_m, 1e-4, 0.1)
    _num("camera.cx_px", c.cx_px, 0.0, c.nx + 1.0, none_ok=True)
    _num("camera.cy_px", c.cy_px, 0.0, c.ny + 1.0, none_ok=True)
    _num("camera.k1", c.k1, -1.0, 1.0)
    _num("camera.k2", c.k2, -1.0, 1.0)
    if c.exit_pupil_m != math.inf:  # inf: image-space telecentric
        _num("camera.exit_pupil_m", c.exit_pupil_m, 1e-3, 1e6, none_ok=True)
    _vec("camera.boresight_rotvec_deg", c.boresight_rotvec_deg, 3, -180.0, 180.0)
    if not isinstance(c.polarizer_deg, tuple) or len(c.polarizer_deg) != 4:
        raise CalibrationError("camera.polarizer_deg: needs 4 numbers")
    for i, nominal in enumerate(NOMINAL_POLARIZER_DEG):  # the camera's Stokes assume this layout
        _num(f"camera.polarizer_deg[{i}]", c.polarizer_deg[i], nominal - 10.0, nominal + 10.0)
    _num("camera.extinction_ratio", c.extinction_ratio, 1.0001, math.inf)
    for i, u in enumerate(cal.compass.unit_installation_deg):
        _vec(f"compass.unit_installation_deg[{i}]", u, 3, -30.0, 30.0)
    _vec("magnetometer.hard_iron_nt", cal.magnetometer.hard_iron_nt, 3, -1e6, 1e6)
    _vec("magnetometer.soft_iron", cal.magnetometer.soft_iron, 9, -10.0, 10.0)
    w = cal.magnetometer.soft_iron
    det = (w[0] * (w[4] * w[8] - w[5] * w[7]) - w[1] * (w[3] * w[8] - w[5] * w[6])
           + w[2] * (w[3] * w[7] - w[4] * w[6]))
    if not abs(det) > 1e-6:
        raise CalibrationError(f"magnetometer.soft_iron: not invertible (determinant {det:g})")


def save_calibration(cal: Calibration, path: str | Path) -> None:
    """Write ``cal`` as JSON (infinite exit pupil as the string ``"inf"``)."""
    d = cal.to_dict()
    if d["camera"]["exit_pupil_m"] is not None and math.isinf(d["camera"]["exit_pupil_m"]):
        d["camera"]["exit_pupil_m"] = "inf"
    Path(path).write_text(json.dumps(d, indent=2) + "\n")


def calibration_from_data(data: Any, where: str = "calibration") -> Calibration:
    """A :class:`Calibration` from the decoded JSON of a calibration file (``where`` names it in errors); the
    reading of a user's file is the emulator's (bounded and confined: ``emulator.dsp.firmware_setup``)."""
    cam = data.get("camera") if isinstance(data, dict) else None
    if isinstance(cam, dict) and cam.get("exit_pupil_m") == "inf":
        cam = dict(cam, exit_pupil_m=math.inf)
        data = dict(data, camera=cam)
    try:
        return Calibration.from_dict(data)
    except CalibrationError as exc:
        raise CalibrationError(f"{where}: {exc}") from exc


def load_calibration(path: str | Path) -> Calibration:
    """Read and check a calibration file (the run's own, written by :func:`save_calibration`); at most
    :data:`MAX_CALIBRATION_BYTES` are read; :class:`CalibrationError` on anything unusable."""
    try:
        with open(path, "rb") as f:
            raw = f.read(MAX_CALIBRATION_BYTES + 1)
        if len(raw) > MAX_CALIBRATION_BYTES:
            raise CalibrationError(f"{path}: larger than {MAX_CALIBRATION_BYTES >> 20} MiB (a calibration file "
                                   "is a few KB)")
        data = json.loads(raw)
    except json.JSONDecodeError as exc:
        raise CalibrationError(f"{path}: line {exc.lineno}, column {exc.colno}: not JSON ({exc.msg})") from None
    except OSError as exc:
        raise CalibrationError(f"{path}: cannot read a calibration file: {exc.strerror or exc}") from None
    except (ValueError, RecursionError) as exc:
        raise CalibrationError(f"{path}: cannot read a calibration file ({type(exc).__name__})") from None
    return calibration_from_data(data, str(path))
