"""Recorded-data injection: a sensor reads a file instead of its model, aligned to the scenario clock.

Formats (``docs/sensors.md`` has the full description):

IMU CSV (``sensors.imu.recorded``)
    Header line with these columns (any order, extra columns ignored), ``#`` comment lines::

        time_s, gyro_x_dps, gyro_y_dps, gyro_z_dps, accel_x_mps2, accel_y_mps2, accel_z_mps2

    Body axes (x right, y forward, z up); angular rate in deg/s, specific force in m/s^2, each
    row the instantaneous value at ``time_s`` (file clock; scenario time = ``time_s`` +
    ``time_offset_s``). At a trigger over ``[t0, t1]`` the sensor outputs the mean of the
    piecewise-linear record over that interval (exact integral), then its own range and
    24-bit words. Outside the record the gyro stays silent (the FPGA flags the missing datagram)
    and the accelerometers hold the last value.

GNSS CSV (``sensors.gnss.recorded: {format: csv}``)
    ``time_s, lat_deg, lon_deg, height_m, vel_e_mps, vel_n_mps, vel_u_mps`` and optional
    ``fix_quality, num_sats, hdop``. Each row is one fix at its epoch; it is sent as NMEA at the
    receiver epoch within half an epoch of it (no row: no fix, no PPS).

GNSS NMEA log (``format: nmea``)
    One sentence per line, checksums verified. Sentences are grouped into epochs by their UTC
    time field (GGA/RMC; other sentences join the epoch they follow) and the original bytes are
    replayed ``latency_s`` after the epoch, with a PPS edge at each epoch that has a valid fix.
    UTC times map to the scenario clock through the scenario epoch's date (or RMC's date).

Polarization images (``sensors.camera.recorded``)
    Raw 12/16-bit mosaics (ny x nx) as 16-bit PNG or TIFF, or NPZ with arrays ``I0, I45, I90,
    I135`` (each either the channel planes, ny/2 x nx/2, or full-resolution demosaiced images,
    from which each channel's own pixels are taken). Frames are timed by an index CSV
    (``time_s, file``) or by a glob with ``rate_hz`` and ``start_s``; a camera capture uses the
    frame within half a frame period of its exposure middle (none: no frame).

A bad file raises :class:`emulator.errors.RecordingError` naming the file, the line and the column.
"""

from __future__ import annotations

import csv
import datetime as _dt
import math
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, cast

import numpy as np

from protocols.constants import DEG
from protocols.gnss import GnssOutputSet
from protocols.nmea import Gga, NmeaFormat, Rmc

from ..errors import RecordingError
from ..links.base import Link
from ..scenario.paths import RECORDED_LINE_MAX, decode_utf8
from .camera import CHANNEL_OFFSETS
from .gnss import GnssConfig, GnssReceiver

if TYPE_CHECKING:
    from ..world.trajectory import Trajectory

__all__ = [
    "GNSS_COLUMNS",
    "IMU_COLUMNS",
    "PHYSICAL_LIMITS",
    "RecordedGnssCsv",
    "RecordedImages",
    "RecordedImu",
    "RecordedNmea",
    "read_mosaic",
    "recorded_gnss",
]

IMU_COLUMNS = ("time_s", "gyro_x_dps", "gyro_y_dps", "gyro_z_dps", "accel_x_mps2", "accel_y_mps2", "accel_z_mps2")
GNSS_COLUMNS = ("time_s", "lat_deg", "lon_deg", "height_m", "vel_e_mps", "vel_n_mps", "vel_u_mps")
GNSS_OPTIONAL = ("fix_quality", "num_sats", "hdop")

#: The physical bounds of a recorded value, per column: (lowest, highest, unit, integer). A finite value outside
#: them is no measurement of anything this box carries (a recorded gyro of 1e300 deg/s, clipped to the STIM210's
#: range, cost 2.3 km of navigation before issue 41): the file is refused at load, naming file, line, column and
#: column, never the cell (docs/hostile-input.md). Rates and forces: wider than any IMU a record may come from (the
#: widest MEMS gyros read +-4000 deg/s, high-g accelerometers +-200 g) [D-4.11]; position, height and speed: the
#: receiver limits the firmware also applies (height -1 km .. 60 km, COCOM speed 515 m/s plus margin); the GGA
#: fields' own ranges (quality 0..9, satellites 0..99, HDOP 0..99.99, NMEA 0183 4.11); time: +-10^9 s (31 years).
PHYSICAL_LIMITS: dict[str, tuple[float, float, str, bool]] = {
    "time_s": (-1e9, 1e9, "s", False),
    **{f"gyro_{a}_dps": (-10_000.0, 10_000.0, "deg/s", False) for a in "xyz"},
    **{f"accel_{a}_mps2": (-2_000.0, 2_000.0, "m/s^2", False) for a in "xyz"},
    "lat_deg": (-90.0, 90.0, "deg", False),
    "lon_deg": (-180.0, 180.0, "deg", False),
    "height_m": (-1_000.0, 60_000.0, "m", False),
    **{f"vel_{a}_mps": (-600.0, 600.0, "m/s", False) for a in "enu"},
    "fix_quality": (0.0, 9.0, "", True),
    "num_sats": (0.0, 99.0, "", True),
    "hdop": (0.0, 99.99, "", False),
}


def _physical(path: Path, line: int, column: int, name: str, v: float, key: str | None = None) -> None:
    """Refuse ``v`` of column ``name`` (bounds of ``key``, default ``name``) when it lies outside its physical
    range (:data:`PHYSICAL_LIMITS`): the error names file, line, column and field, never the value."""
    lim = PHYSICAL_LIMITS.get(key or name)
    if lim is None:
        return
    lo, hi, unit, integer = lim
    if not lo <= v <= hi:
        raise RecordingError(f"{path}: line {line}, column {column}: {name} is outside its physical range "
                             f"[{lo:g}, {hi:g}]{' ' + unit if unit else ''}")
    if integer and v != int(v):
        raise RecordingError(f"{path}: line {line}, column {column}: {name} is not an integer")




def _csv_cells(path: Path, i: int, ln: str) -> list[str]:
    try:
        return next(csv.reader([ln]))
    except csv.Error as exc:  # never the cell's text (docs/hostile-input.md section 6)
        raise RecordingError(f"{path}: line {i + 1}: not a CSV row ({type(exc).__name__})") from None


def _read_csv(path: Path, required: tuple[str, ...], optional: tuple[str, ...] = ()) -> dict[str, np.ndarray]:
    """Numeric columns of a CSV with a header; errors name file, line and column (1-based). The file must be UTF-8
    with lines of at most :data:`RECORDED_LINE_MAX` characters."""
    path = Path(path)
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise RecordingError(f"{path}: cannot read: {exc.strerror or exc}") from exc
    lines = decode_utf8(raw, path).splitlines()
    for i, ln in enumerate(lines):
        if len(ln) > RECORDED_LINE_MAX:
            raise RecordingError(f"{path}: line {i + 1}, column {RECORDED_LINE_MAX + 1}: line longer than "
                                 f"{RECORDED_LINE_MAX} characters ({len(ln)})")
    header_line = None
    for i, ln in enumerate(lines):
        if ln.strip() and not ln.lstrip().startswith("#"):
            header_line = i
            break
    if header_line is None:
        raise RecordingError(f"{path}: line 1, column 1: empty file (expected a header: {', '.join(required)})")
    header = [h.strip() for h in _csv_cells(path, header_line, lines[header_line])]
    missing = [c for c in required if c not in header]
    if missing:
        raise RecordingError(f"{path}: line {header_line + 1}, column 1: missing column(s) {', '.join(missing)} "
                             f"(the header has {len(header)} columns)")  # never the file's text (docs/hostile-input.md)
    want = [c for c in required + optional if c in header]
    idx = {c: header.index(c) for c in want}
    rows: dict[str, list[float]] = {c: [] for c in want}
    for i in range(header_line + 1, len(lines)):
        ln = lines[i]
        if not ln.strip() or ln.lstrip().startswith("#"):
            continue
        cells = _csv_cells(path, i, ln)
        starts = [0]
        for c in cells[:-1]:
            starts.append(starts[-1] + len(c) + 1)
        for c in want:
            j = idx[c]
            if j >= len(cells):
                raise RecordingError(f"{path}: line {i + 1}, column {len(ln) + 1}: row has {len(cells)} fields, "
                                     f"column {c!r} is field {j + 1}")
            try:
                v = float(cells[j])
            except ValueError:
                raise RecordingError(f"{path}: line {i + 1}, column {starts[j] + 1}: {c} "
                                     f"({len(cells[j])} characters) is not a number") from None
            if not math.isfinite(v):
                raise RecordingError(f"{path}: line {i + 1}, column {starts[j] + 1}: {c} is not finite")
            _physical(path, i + 1, starts[j] + 1, c, v)
            rows[c].append(v)
    out = {c: np.array(v, dtype=np.float64) for c, v in rows.items()}
    t = out[required[0]]
    if len(t) < 1:
        raise RecordingError(f"{path}: line {header_line + 2}, column 1: no data rows")
    bad = np.nonzero(np.diff(t) <= 0)[0]
    if len(bad):
        raise RecordingError(f"{path}: data row {bad[0] + 2}, column {idx[required[0]] + 1}: {required[0]} "
                             f"is not increasing ({t[bad[0]]:g} then {t[bad[0] + 1]:g})")
    return out


class RecordedImu:
    """Gyro and accelerometer samples from an IMU CSV (see module docstring)."""

    def __init__(self, path: Path | str, time_offset_s: float = 0.0) -> None:
        self.path = Path(path)
        d = _read_csv(self.path, IMU_COLUMNS)
        if len(d["time_s"]) < 2:
            raise RecordingError(f"{self.path}: line 3, column 1: an IMU record needs at least two rows")
        self.t = d["time_s"] + time_offset_s
        self.w = np.stack([d["gyro_x_dps"], d["gyro_y_dps"], d["gyro_z_dps"]], axis=1) * DEG
        self.f = np.stack([d["accel_x_mps2"], d["accel_y_mps2"], d["accel_z_mps2"]], axis=1)
        dt = np.diff(self.t)[:, None]
        self._cw = np.concatenate([np.zeros((1, 3)), np.cumsum(0.5 * (self.w[1:] + self.w[:-1]) * dt, axis=0)])
        self._cf = np.concatenate([np.zeros((1, 3)), np.cumsum(0.5 * (self.f[1:] + self.f[:-1]) * dt, axis=0)])

    def _integral(self, cum: np.ndarray, val: np.ndarray, t: float) -> np.ndarray:
        i = int(np.clip(np.searchsorted(self.t, t, side="right") - 1, 0, len(self.t) - 2))
        h = self.t[i + 1] - self.t[i]
        s = t - self.t[i]
        slope = (val[i + 1] - val[i]) / h
        return cum[i] + val[i] * s + 0.5 * slope * s * s

    def covers(self, t0: float, t1: float) -> bool:
        return self.t[0] <= t0 and t1 <= self.t[-1]

    def mean_rate(self, t0: float, t1: float) -> np.ndarray | None:
        """Mean angular rate (rad/s, body) over ``[t0, t1]``; None outside the record."""
        if not self.covers(t0, t1):
            return None
        return (self._integral(self._cw, self.w, t1) - self._integral(self._cw, self.w, t0)) / (t1 - t0)

    def mean_specific_force(self, t0: float, t1: float) -> np.ndarray:
        """Mean specific force (m/s^2, body) over ``[t0, t1]``; the nearest end value outside the record."""
        if t1 <= self.t[0]:
            return self.f[0].copy()
        if t0 >= self.t[-1]:
            return self.f[-1].copy()
        a, b = max(t0, self.t[0]), min(t1, self.t[-1])
        return (self._integral(self._cf, self.f, b) - self._integral(self._cf, self.f, a)) / (b - a)


class RecordedGnssCsv:
    """Fixes from a GNSS CSV; :meth:`fix_at` returns the row of an epoch or None."""

    def __init__(self, path: Path | str, time_offset_s: float = 0.0) -> None:
        self.path = Path(path)
        d = _read_csv(self.path, GNSS_COLUMNS, GNSS_OPTIONAL)
        self.t = d["time_s"] + time_offset_s
        self.d = d

    def fix_at(self, t: float, half_window: float = 0.5) -> dict[str, float] | None:
        i = int(np.argmin(np.abs(self.t - t)))
        if abs(self.t[i] - t) > half_window:
            return None
        return {k: float(v[i]) for k, v in self.d.items()}


class _CsvReplayReceiver(GnssReceiver):
    """A GNSS receiver that sends the recorded fixes instead of truth plus errors."""

    def __init__(self, link: Link, src: RecordedGnssCsv, epoch: _dt.datetime, cfg: GnssConfig,
                 pps: Callable[[float], None] | None, rng: np.random.Generator) -> None:
        # the receiver's truth is never read: it replays the recorded fixes instead
        super().__init__(link, cast("Trajectory", _NoTruth()), epoch, rng, cfg, pps)
        self.src = src

    def has_fix(self, t: float) -> bool:
        return self.src.fix_at(t, 0.5 / self.cfg.rate_hz) is not None

    def sentences(self, t: float, fix: bool = True, output: GnssOutputSet | None = None) -> bytes:
        from protocols.gnss import build_epoch

        cfg = self.cfg
        utc = self.epoch + _dt.timedelta(seconds=t)
        row = self.src.fix_at(t, 0.5 / cfg.rate_hz)
        if row is None:
            return super().sentences(t, False, output)
        q = int(row.get("fix_quality", cfg.fix_quality))
        f = self._fix(utc, row["lat_deg"], row["lon_deg"], row["height_m"],
                      (row["vel_e_mps"], row["vel_n_mps"], row.get("vel_u_mps", 0.0)),
                      fix_type=3 if q > 0 else 0, quality=q)
        self.fixes_sent += 1
        return build_epoch(f, output if output is not None else self._output)


class _NoTruth:
    """Placeholder trajectory for replaying receivers (they never read truth)."""

    duration = math.inf

    def state(self, t: float):  # pragma: no cover - never called
        raise RecordingError("a recorded GNSS source does not use truth")


def _nmea_physical(path: Path, line: int, col: int, msg: Gga | Rmc) -> None:
    """Refuse a GGA or RMC of a recorded log whose position, height or speed is not physical (or not finite)."""
    kind = type(msg).__name__.upper()
    vals: list[tuple[str, float | None, str]] = [("latitude", msg.lat_deg, "lat_deg"),
                                                  ("longitude", msg.lon_deg, "lon_deg")]
    if isinstance(msg, Gga):
        h = None if msg.altitude_msl_m is None else msg.altitude_msl_m + (msg.geoid_sep_m or 0.0)
        vals.append(("height", h, "height_m"))
    else:
        vals.append(("speed", msg.speed_mps, "vel_e_mps"))
    for name, v, key in vals:
        if v is None:
            continue
        if not math.isfinite(v):
            raise RecordingError(f"{path}: line {line}, column {col}: {kind} {name} is not finite")
        _physical(path, line, col, f"{kind} {name}", abs(v) if name == "speed" else v, key)


class RecordedNmea:
    """An NMEA log grouped into epochs: ``epochs`` is a list of ``(t_s, bytes, has_fix)``."""

    def __init__(self, path: Path | str, epoch: _dt.datetime, time_offset_s: float = 0.0) -> None:
        self.path = Path(path)
        try:
            raw = self.path.read_bytes()
        except OSError as exc:
            raise RecordingError(f"{self.path}: cannot read: {exc.strerror or exc}") from exc
        fmt = NmeaFormat()
        groups: list[list] = []  # [t, bytearray, fix]
        date = epoch.date()
        for i, line in enumerate(raw.splitlines(), start=1):
            if not line.strip():
                continue
            s = line.strip()
            col = line.index(s[:1]) + 1
            if not s.startswith(b"$"):
                raise RecordingError(f"{self.path}: line {i}, column {col}: not an NMEA sentence (no '$')")
            star = s.rfind(b"*")
            if star < 0 or len(s) < star + 3:
                raise RecordingError(f"{self.path}: line {i}, column {col + len(s)}: NMEA sentence without checksum")
            frame = s[:star + 3] + b"\r\n"
            if not fmt.check(frame):
                raise RecordingError(f"{self.path}: line {i}, column {col + star}: NMEA checksum mismatch")
            try:
                msg = fmt.parse(frame)
            except Exception as exc:
                raise RecordingError(f"{self.path}: line {i}, column {col}: bad NMEA sentence: {exc}") from exc
            if isinstance(msg, (Gga, Rmc)):
                _nmea_physical(self.path, i, col, msg)
            tm = msg.time_utc if isinstance(msg, (Gga, Rmc)) else None
            if isinstance(msg, Rmc) and msg.date is not None:
                date = msg.date
            if tm is not None:
                utc = _dt.datetime.combine(date, tm, tzinfo=_dt.UTC)
                t = (utc - epoch).total_seconds() + time_offset_s
                if not groups or abs(groups[-1][0] - t) > 1e-6:
                    groups.append([t, bytearray(), False])
                if isinstance(msg, Gga):
                    groups[-1][2] = groups[-1][2] or bool(getattr(msg, "quality", 0))
                elif isinstance(msg, Rmc):
                    groups[-1][2] = groups[-1][2] or bool(getattr(msg, "valid", False))
            if not groups:
                continue  # sentences before the first time-tagged one have no epoch
            groups[-1][1] += frame
        if not groups:
            raise RecordingError(f"{self.path}: line 1, column 1: no time-tagged GGA/RMC sentence")
        self.epochs = [(g[0], bytes(g[1]), g[2]) for g in groups]


class _NmeaReplay:
    """Replays a :class:`RecordedNmea` on a link with PPS edges (a GNSS device without a model)."""

    def __init__(self, link: Link, log: RecordedNmea, latency_s: float, pps: Callable[[float], None] | None) -> None:
        self.link = link
        self.log = log
        self.latency_s = latency_s
        self.pps = pps
        self.epochs_sent = 0

    def start(self) -> None:
        for t, data, fix in self.log.epochs:
            if t < 0:
                continue
            if fix and self.pps is not None:
                self.link.loop.call_at(t, self.pps, t)
            self.link.loop.call_at(t + self.latency_s, self._send, data)

    def _send(self, data: bytes) -> None:
        self.link.send(data)
        self.epochs_sent += 1


def recorded_gnss(link: Link, path: Path, fmt: str, epoch: _dt.datetime, cfg: GnssConfig, time_offset_s: float,
                  pps: Callable[[float], None] | None, rng: np.random.Generator):
    """The GNSS device of a recorded file (``csv`` or ``nmea``)."""
    if fmt == "nmea":
        return _NmeaReplay(link, RecordedNmea(path, epoch, time_offset_s), cfg.latency_s, pps)
    return _CsvReplayReceiver(link, RecordedGnssCsv(path, time_offset_s), epoch, cfg, pps, rng)


def read_mosaic(path: Path | str, shape: tuple[int, int]) -> np.ndarray:
    """A raw mosaic (ny, nx) uint16 from a 16-bit PNG/TIFF or an NPZ with I0/I45/I90/I135."""
    path = Path(path)
    ny, nx = shape
    suffix = path.suffix.lower()
    try:
        if suffix == ".npz":
            with np.load(path) as z:
                missing = [k for k in ("I0", "I45", "I90", "I135") if k not in z]
                if missing:
                    raise RecordingError(f"{path}: line 1, column 1: NPZ lacks array(s) {', '.join(missing)}")
                out = np.empty((ny, nx), dtype=np.uint16)
                for theta, (r, c) in CHANNEL_OFFSETS.items():
                    a = np.asarray(z[f"I{theta}"])
                    if a.shape == (ny // 2, nx // 2):
                        plane = a
                    elif a.shape == (ny, nx):
                        plane = a[r::2, c::2]
                    else:
                        raise RecordingError(f"{path}: line 1, column 1: I{theta} has shape {a.shape}, expected "
                                             f"{(ny // 2, nx // 2)} or {(ny, nx)}")
                    _check_dn(path, f"I{theta}", plane)
                    out[r::2, c::2] = np.round(plane).astype(np.uint16)
                return out
        if suffix in (".png", ".tif", ".tiff"):
            from PIL import Image

            with Image.open(path) as im:
                a = np.array(im)
        else:
            raise RecordingError(f"{path}: line 1, column 1: unknown image type {suffix!r} (png, tif, tiff, npz)")
    except RecordingError:
        raise
    except (OSError, ValueError) as exc:
        raise RecordingError(f"{path}: line 1, column 1: cannot read image: {exc}") from exc
    if a.ndim != 2 or a.shape != (ny, nx):
        raise RecordingError(f"{path}: line 1, column 1: image has shape {a.shape}, expected a raw mosaic {(ny, nx)}")
    if a.dtype.kind not in "ui":
        raise RecordingError(f"{path}: line 1, column 1: image has dtype {a.dtype}, expected integer DN")
    _check_dn(path, "image", a)
    return a.astype(np.uint16)


def _check_dn(path: Path, name: str, a: np.ndarray) -> None:
    """Refuse pixel values that no camera gives: not finite, negative, or beyond 16 bits (before issue 41 an NPZ
    value of -5 or 1e300 was clipped silently into the mosaic)."""
    if a.size == 0:
        return
    if a.dtype.kind == "f" and not np.isfinite(a).all():
        raise RecordingError(f"{path}: line 1, column 1: {name} holds a value that is not finite")
    if a.dtype.kind == "b" or a.dtype.kind not in "uif":
        raise RecordingError(f"{path}: line 1, column 1: {name} has dtype {a.dtype}, expected numeric DN")
    lo, hi = float(a.min()), float(a.max())
    if lo < -0.5 or hi >= 65535.5:  # what rounds into 0 .. 65535
        raise RecordingError(f"{path}: line 1, column 1: {name} holds pixel values outside [0, 65535] DN")


class RecordedImages:
    """Timed raw mosaics for the camera (see module docstring); :meth:`mosaic_at` is the camera's source."""

    def __init__(self, index: Path | None = None, files: str | None = None, rate_hz: float | None = None,
                 start_s: float = 0.0, shape: tuple[int, int] = (2048, 2448),
                 base_dir: str | Path | None = None) -> None:
        """``index`` (a confined path) or ``files`` (a glob relative to ``base_dir``, the scenario's directory):
        every index entry and every glob match is confined to the scenario's directory
        (:mod:`emulator.scenario.paths`) before it is looked at, with the same message whether it exists or not.
        Without ``base_dir``: the index's directory, or the working directory for a glob."""
        from ..scenario.paths import PathNotAllowed, confined_glob, read_frame_index

        self.shape = shape
        if index is not None:
            d = read_frame_index(Path(index), base_dir if base_dir is not None else Path(index).parent)
            self.times = d[0]
            self.files = d[1]
        else:
            try:
                found = confined_glob(base_dir, str(files), "camera frame")
            except PathNotAllowed as exc:
                raise RecordingError(f"{files}: {exc}") from None
            if not found:
                raise RecordingError(f"{files}: line 1, column 1: no file matches")
            self.files = found
            self.times = start_s + np.arange(len(found)) / float(rate_hz)  # type: ignore[arg-type]
        self.period = float(np.median(np.diff(self.times))) if len(self.times) > 1 else math.inf
        self._cache: tuple[int, np.ndarray] | None = None

    def mosaic_at(self, t: float) -> np.ndarray | None:
        i = int(np.argmin(np.abs(self.times - t)))
        if abs(self.times[i] - t) > 0.5 * min(self.period, 1e9):
            return None
        if self._cache is None or self._cache[0] != i:
            self._cache = (i, read_mosaic(self.files[i], self.shape))
        return self._cache[1]
