"""Map a scenario onto the firmware's build/run-time configuration."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from firmware_model import FirmwareConfig
from firmware_model.attitude import a2mat, yaw_from_heading
from firmware_model.calibration import (
    MAX_CALIBRATION_BYTES,
    NOMINAL_POLARIZER_DEG,
    Calibration,
    CalibrationError,
    CameraCalibration,
    CompassCalibration,
    MagnetometerCalibration,
    calibration_from_data,
)
from firmware_model.config import FILTER_VARIANTS
from firmware_model.psns_geometry import (
    CameraGeometry,
    calibrated_mountings,
    camera_from_calibration,
    compass_unit_mountings,
)
from firmware_model.registry import (
    BUILTIN_FILTER_PARAMS,
    FIRMWARE_IMPLEMENTATIONS,
    FirmwareProtocol,
    filter_params_model,
)
from firmware_model.spec_sheet import SensorSpecSheet, SpecSheetError
from firmware_model.variants.common import compass_mountings
from protocols.constants import DEG

from ..devices.base import device_rng
from ..devices.compass import default_mountings, mountings_from_directions, turned_about_view_rays
from ..devices.sensors import (
    InstalledUnit,
    accel_errors,
    gyro_errors,
    installed_unit,
)
from ..errors import RecordingError, ScenarioError
from ..plugins import PLUGIN_ERRORS, plugin, plugin_names
from ..scenario.paths import PathNotAllowed, confine, read_json_bounded
from ..scenario.resolved import ResolvedSensors
from ..scenario.schema import Scenario
from .variant_params import variant_params

__all__ = ["SPEC_SHEET_DIR", "build_firmware", "calibration_for", "check_firmware", "firmware_config",
           "register_plugins", "spec_sheet_for"]

#: the spec sheets bundled with the firmware (``firmware.spec_sheet: <name>``)
SPEC_SHEET_DIR = Path(__file__).resolve().parents[2] / "firmware_model" / "spec_sheets"



def _rotvec_deg(c: np.ndarray) -> tuple[float, float, float]:
    x, y, z = (float(a) for a in np.degrees(Rotation.from_matrix(c).as_rotvec()))
    return x, y, z


def calibration_for(scn: Scenario, seed: int | None = None, unit: InstalledUnit | None = None) -> Calibration:
    """The calibration file the DSP gets (``firmware.calibration``): the sensors' truth plus residuals drawn with
    the run's seed, the truth itself, the design values, or the user's file (confined to the scenario's
    directory). This is the one place where the world's truth reaches the firmware, and only through the file.
    Sections: the camera (when fitted), the compass's per-unit installation angles (when fitted) and the
    magnetometer's hard and soft iron (when fitted); each residual draw has its own random stream, so adding a
    sensor does not change another's draw. ``unit``: the installed unit the sensor models were built with (default:
    :func:`emulator.devices.sensors.installed_unit` of ``scn`` and ``seed``): the truth is drawn once and shared."""
    spec = scn.firmware.calibration
    seed = scn.seed if seed is None else seed
    if spec.source == "file":
        assert spec.file is not None
        try:  # confined and bounded as every file a scenario names (docs/hostile-input.md section 6)
            path = confine(scn.base_dir, spec.file, "calibration file")
            data = read_json_bounded(path, MAX_CALIBRATION_BYTES, "calibration file")
            return calibration_from_data(data, str(path))
        except (PathNotAllowed, RecordingError, CalibrationError) as exc:
            raise ScenarioError(f"{scn.source_file}: firmware.calibration.file: {exc}") from None
    if unit is None:
        unit = installed_unit(scn, seed)
    return Calibration(camera=_camera_calibration(scn, seed, unit), compass=_compass_calibration(scn, seed, unit),
                       magnetometer=_mag_calibration(scn, seed, unit))


def _camera_calibration(scn: Scenario, seed: int, unit: InstalledUnit) -> CameraCalibration:
    spec = scn.firmware.calibration
    if scn.sensors.camera is None:
        return CameraCalibration()
    cc = unit.camera
    m = scn.sensors.camera.mounting
    if spec.source == "nominal":  # the design: the lens drawing and the nominal mount, no bench measurement
        nominal_c_b = a2mat(m.pitch_deg * DEG, m.roll_deg * DEG, yaw_from_heading(m.heading_deg * DEG))
        return CameraCalibration(
            projection=cc.lens, nx=cc.nx, ny=cc.ny, pixel_m=cc.pixel_m, focal_m=cc.focal_m,
            boresight_rotvec_deg=_rotvec_deg(nominal_c_b), extinction_ratio=min(cc.extinction_ratio, 1e9))
    truth = CameraCalibration(
        projection=cc.lens, nx=cc.nx, ny=cc.ny, pixel_m=cc.pixel_m, focal_m=cc.focal_m,
        cx_px=cc.lens_model.cx, cy_px=cc.lens_model.cy, k1=cc.k1, k2=cc.k2, exit_pupil_m=cc.exit_pupil_m,
        boresight_rotvec_deg=_rotvec_deg(cc.mounting_c_b),
        polarizer_deg=tuple(th + b for th, b in zip(NOMINAL_POLARIZER_DEG,  # type: ignore[arg-type]
                                                     cc.defects.orientation_bias_deg, strict=True)),
        extinction_ratio=min(cc.extinction_ratio, 1e9))
    if spec.source == "perfect":
        return truth
    r = spec.residuals
    rng = device_rng(seed, "calibration")
    err = Rotation.from_rotvec(np.radians(r.boresight_deg * rng.standard_normal(3)))
    c_b = cc.mounting_c_b @ err.as_matrix()
    pp = r.principal_point_px * rng.standard_normal(2)
    if spec.source == "lab":  # the lens as a bench fit in the firmware's family; the rest as "residuals"
        focal_m, cx, cy, k1, k2 = lab_lens_fit(cc, device_rng(seed, "calibration_lab"))
        return replace(
            truth, focal_m=focal_m, cx_px=cx, cy_px=cy, k1=k1, k2=k2,
            exit_pupil_m=None if truth.exit_pupil_m is None
            else truth.exit_pupil_m * (1.0 + r.exit_pupil_rel * float(rng.standard_normal())),
            boresight_rotvec_deg=_rotvec_deg(c_b),
            polarizer_deg=tuple(a + r.polarizer_deg * float(rng.standard_normal())  # type: ignore[arg-type]
                                for a in truth.polarizer_deg))
    return replace(
        truth, focal_m=truth.focal_m * (1.0 + r.focal_rel * float(rng.standard_normal())),
        cx_px=float(cc.lens_model.cx + pp[0]), cy_px=float(cc.lens_model.cy + pp[1]),
        k1=truth.k1 + r.distortion_k1 * float(rng.standard_normal()),
        exit_pupil_m=None if truth.exit_pupil_m is None
        else truth.exit_pupil_m * (1.0 + r.exit_pupil_rel * float(rng.standard_normal())),
        boresight_rotvec_deg=_rotvec_deg(c_b),
        polarizer_deg=tuple(a + r.polarizer_deg * float(rng.standard_normal())  # type: ignore[arg-type]
                            for a in truth.polarizer_deg))


#: the lab calibration's bench: a collimated point source on a two-axis stage imaged at LAB_GRID x LAB_GRID places
#: across the sensor (the stage's angles known), centroids with LAB_CENTROID_PX rms noise (design values [D])
LAB_GRID = 25
LAB_CENTROID_PX = 0.05


def lab_lens_fit(cc: Any, rng: np.random.Generator) -> tuple[float, float, float, float, float]:
    """A lab calibration of the camera ``cc`` (the world's :class:`CameraConfig`, the true lens) in the firmware's
    lens family: ``(focal_m, cx_px, cy_px, k1, k2)`` that best map the bench's known directions onto their observed
    centroids (least squares, scipy). The family is the calibration file's documented one (docs/calibration.md:
    principal point, focal length, radial ``k1``, ``k2`` on ``tan(theta)`` for pinhole, on ``theta`` for fisheye),
    written here from that format, not borrowed from the firmware's code. A true lens outside the family
    (``k3``, decentering) leaves a model-form residual the firmware cannot know (docs/sensors.md, "The envelope")."""
    from scipy.optimize import least_squares

    lens = cc.lens_model
    m = 40.0
    gx = np.linspace(m, cc.nx - m, LAB_GRID)
    gy = np.linspace(m, cc.ny - m, LAB_GRID)
    X, Y = np.meshgrid(gx, gy)
    v, th, _, _ = lens.rays(X.ravel(), Y.ravel())
    ok = np.isfinite(th)
    v = v[:, ok]
    u_obs = X.ravel()[ok] + LAB_CENTROID_PX * rng.standard_normal(int(ok.sum()))
    w_obs = Y.ravel()[ok] + LAB_CENTROID_PX * rng.standard_normal(int(ok.sum()))
    theta = np.arccos(np.clip(v[2], -1.0, 1.0))
    alpha = np.arctan2(v[1], v[0])
    base = np.tan(theta) if cc.lens == "pinhole" else theta

    def residual(p: np.ndarray) -> np.ndarray:
        f_px, cx, cy, k1, k2 = p
        rho = base * (1.0 + k1 * base ** 2 + k2 * base ** 4)
        return np.concatenate([cx + f_px * rho * np.cos(alpha) - u_obs, cy + f_px * rho * np.sin(alpha) - w_obs])

    p0 = np.array([cc.focal_m / cc.pixel_m, (cc.nx + 1) / 2.0, (cc.ny + 1) / 2.0, 0.0, 0.0])
    sol = least_squares(residual, p0, x_scale=np.array([10.0, 1.0, 1.0, 1e-3, 1e-3]), method="lm")
    f_px, cx, cy, k1, k2 = (float(x) for x in sol.x)
    return f_px * cc.pixel_m, cx, cy, k1, k2


def _compass_calibration(scn: Scenario, seed: int, unit: InstalledUnit) -> CompassCalibration:
    """Per-unit installation angles: the rotation (about the unit's own axes) from the nominal unit to the installed
    one, ``R_u = C_u,nominal^T C_u,true`` (truth), plus a residual per axis; empty for ``nominal`` (the layout
    drawing) and when no compass is fitted. The scenario's ``aop_offset_deg`` is the E-vector error the calibration
    *left* (Zhang et al.'s Table 2, "after calibration"): it is not in what the calibration measured, so the units'
    turn about their view rays by it is taken out of the truth first (D-5.26; before, the calibration file handed the
    firmware the very residuals it was meant to keep)."""
    spec = scn.firmware.calibration
    c = scn.sensors.compass
    if c is None or not c.enabled or spec.source == "nominal":
        return CompassCalibration()
    true = unit.compass.mountings
    if c.aop_offset_deg is not None:
        true = turned_about_view_rays(true, -np.asarray(c.aop_offset_deg, dtype=np.float64) * DEG)
    nominal = (mountings_from_directions([(u.zenith_deg, u.azimuth_deg) for u in c.units]) if c.units is not None
               else default_mountings())
    rv = np.stack([Rotation.from_matrix(n.T @ t).as_rotvec(degrees=True) for n, t in zip(nominal, true, strict=True)])
    if spec.source == "residuals":
        rv = rv + spec.residuals.compass_installation_deg * device_rng(seed, "calibration_compass").standard_normal(
            rv.shape)
    return CompassCalibration(unit_installation_deg=tuple(
        (float(a), float(b), float(g)) for a, b, g in rv))


def _mag_calibration(scn: Scenario, seed: int, unit: InstalledUnit) -> MagnetometerCalibration:
    """Hard and soft iron: the magnetometer's truth plus a residual (hard iron per axis; soft iron per element,
    kept symmetric); the identity for ``nominal`` and when no magnetometer is fitted."""
    spec = scn.firmware.calibration
    m = scn.sensors.magnetometer
    if m is None or not m.enabled or spec.source == "nominal":
        return MagnetometerCalibration()
    mc = unit.magnetometer
    h = np.asarray(mc.hard_iron_nt, dtype=np.float64)
    w = np.asarray(mc.soft_iron, dtype=np.float64)
    if spec.source == "residuals":
        r = spec.residuals
        rng = device_rng(seed, "calibration_mag")
        h = h + r.mag_hard_iron_nt * rng.standard_normal(3)
        e = np.triu(r.mag_soft_iron * rng.standard_normal((3, 3)))
        w = w + e + np.triu(e, 1).T
    return MagnetometerCalibration(hard_iron_nt=(float(h[0]), float(h[1]), float(h[2])),
                                   soft_iron=tuple(float(x) for x in w.ravel()))


def spec_sheet_for(scn: Scenario) -> SensorSpecSheet:
    """The firmware's sensor spec sheet (``firmware.spec_sheet``): a bundled sheet by name, or a YAML file confined to
    the scenario's directory. The world's presets never reach the firmware (docs/firmware.md "Spec sheet")."""
    import yaml

    ref = scn.firmware.spec_sheet
    if "/" not in ref and not ref.endswith((".yaml", ".yml")):
        path = SPEC_SHEET_DIR / f"{ref}.yaml"
        if not path.is_file():
            names = sorted(p.stem for p in SPEC_SHEET_DIR.glob("*.yaml"))
            raise ScenarioError(f"firmware.spec_sheet: no bundled spec sheet {ref!r} (bundled: {', '.join(names)})")
    else:  # the scenario's own file: confined as every file it names, read as boundedly as the scenario itself
        from ..scenario.paths import PathNotAllowed, confine

        try:
            path = confine(scn.base_dir, ref, "spec sheet")
        except PathNotAllowed:
            raise ScenarioError(f"firmware.spec_sheet: {ref} is outside the scenario's directory") from None
        if not path.is_file():
            raise ScenarioError(f"firmware.spec_sheet: {ref}: no such file")
    try:
        if path.parent == SPEC_SHEET_DIR:
            data = yaml.safe_load(path.read_text(encoding="utf-8"))  # bundled with the package: trusted
        else:
            from ..scenario.loader import load_yaml_file

            data = load_yaml_file(path, f"firmware.spec_sheet: {ref}")
        return SensorSpecSheet.from_dict(data, f"firmware.spec_sheet: {ref}")
    except (OSError, yaml.YAMLError) as exc:
        raise ScenarioError(f"firmware.spec_sheet: {ref}: {exc}") from exc
    except SpecSheetError as exc:
        raise ScenarioError(str(exc)) from exc


def _camera(scn: Scenario, calibration: Calibration) -> CameraGeometry:
    """The firmware's camera model: its calibration file, then any ``firmware.psns.camera`` override."""
    cal = scn.firmware.psns.camera
    cam = camera_from_calibration(calibration.camera)
    if all(v is None for v in cal.model_dump().values()):
        return cam
    pick = lambda v, default: default if v is None else v  # noqa: E731
    if any(v is not None for v in (cal.mounting_heading_deg, cal.mounting_pitch_deg, cal.mounting_roll_deg)):
        m = scn.sensors.camera.mounting if scn.sensors.camera is not None else None
        c_c_b = a2mat(pick(cal.mounting_pitch_deg, m.pitch_deg if m else 0.0) * DEG,
                      pick(cal.mounting_roll_deg, m.roll_deg if m else 0.0) * DEG,
                      yaw_from_heading(pick(cal.mounting_heading_deg, m.heading_deg if m else 0.0) * DEG))
    else:
        c_c_b = cam.c_c_b
    pixel_m = cal.pixel_um * 1e-6 if cal.pixel_um is not None else cam.dx_m
    return replace(cam, nx=pick(cal.nx, cam.nx), ny=pick(cal.ny, cam.ny), dx_m=pixel_m, dy_m=pixel_m,
                   focal_m=cal.focal_mm * 1e-3 if cal.focal_mm is not None else cam.focal_m,
                   projection=pick(cal.projection, cam.projection), c_c_b=c_c_b)


def register_plugins(filters: Iterable[str] | None = None, firmware: Iterable[str] | None = None) -> None:
    """Enter ``psns_hil.filters`` and ``psns_hil.firmware`` entry points (:mod:`emulator.plugins`) in the
    firmware's tables (:data:`firmware_model.FILTER_VARIANTS`,
    :data:`firmware_model.registry.FIRMWARE_IMPLEMENTATIONS`): only the names given (a run imports the plugins its
    scenario names, nothing else: issue 41), every installed one when a group's names are None. A built-in name is
    never replaced; what cannot be entered (fails to import, not a ``NavFilter`` subclass, a firmware factory that
    is not callable) is kept in :data:`emulator.plugins.PLUGIN_ERRORS`."""
    from firmware_model.config import FILTER_VARIANTS
    from firmware_model.filters.interface import NavFilter, register_filter
    from firmware_model.registry import register_firmware

    installed = plugin_names("psns_hil.filters")
    for name in installed if filters is None else [n for n in filters if n in installed]:
        if name in FILTER_VARIANTS:
            if getattr(FILTER_VARIANTS[name], "__module__", "").startswith("firmware_model."):
                PLUGIN_ERRORS.setdefault(("psns_hil.filters", name), f"the name {name!r} is built in; not replaced")
            continue
        cls = plugin("psns_hil.filters", name)
        if cls is None:
            continue
        if not (isinstance(cls, type) and issubclass(cls, NavFilter)):
            PLUGIN_ERRORS[("psns_hil.filters", name)] = "not a firmware_model.filters.interface.NavFilter subclass"
            continue
        register_filter(name)(cls)
    installed = plugin_names("psns_hil.firmware")
    for name in installed if firmware is None else [n for n in firmware if n in installed]:
        if name in FIRMWARE_IMPLEMENTATIONS:
            continue
        factory = plugin("psns_hil.firmware", name)
        if callable(factory):
            register_firmware(name, factory)
        elif factory is not None:
            PLUGIN_ERRORS[("psns_hil.firmware", name)] = "not callable: FirmwareConfig -> FirmwareProtocol expected"


def check_firmware(scn: Scenario) -> None:
    """What ``psns-hil validate`` checks beyond the scenario's schema on the firmware side, without running
    anything: the named filter and firmware plugins load and are of their kind (a ``NavFilter`` subclass, a
    callable factory), the spec sheet and a user's calibration file read and validate (:func:`spec_sheet_for`,
    :func:`calibration_for`). Raises :class:`ScenarioError` naming the field."""
    fw = scn.firmware
    register_plugins((fw.filter,), (fw.implementation,))
    if fw.filter not in FILTER_VARIANTS:
        why = PLUGIN_ERRORS.get(("psns_hil.filters", fw.filter), "not registered")
        raise ScenarioError(f"{scn.source_file}: firmware.filter: {fw.filter!r} cannot be used: {why}")
    if fw.implementation not in FIRMWARE_IMPLEMENTATIONS:
        why = PLUGIN_ERRORS.get(("psns_hil.firmware", fw.implementation), "not registered")
        raise ScenarioError(f"{scn.source_file}: firmware.implementation: {fw.implementation!r} cannot be used: "
                            f"{why}")
    spec_sheet_for(scn)
    if fw.calibration.source == "file":
        calibration_for(scn)


def _plugin_params(scn: Scenario) -> dict[str, object]:
    """``firmware.params`` of a filter added by entry point, as an instance of the model it declares (validated
    by the scenario schema; a built-in variant's are merged into ``firmware.variants`` there)."""
    name = scn.firmware.filter
    if name in BUILTIN_FILTER_PARAMS:
        return {}
    register_plugins((name,), ())
    model = filter_params_model(name)
    if model is None:
        return {}
    from pydantic import TypeAdapter

    return {name: TypeAdapter(model).validate_python(scn.firmware.params)}


def _compass_mountings(scn: Scenario, calibration: Calibration):
    """The compass's units as the firmware knows them: its own nominal layout (the scenario's unit directions, or
    the default 9 units) turned by the calibrated installation angles of the calibration file; None: the default 9
    units with no installation angles."""
    c = scn.sensors.compass
    angles = calibration.compass.unit_installation_deg
    if (c is None or c.units is None) and not angles:
        return None
    nominal = (compass_mountings([(u.zenith_deg, u.azimuth_deg) for u in c.units])
               if c is not None and c.units is not None else compass_unit_mountings())
    try:
        return calibrated_mountings(nominal, angles)
    except ValueError as exc:
        raise ScenarioError(f"firmware.calibration: {exc}") from exc


def _vec3(v: Any) -> tuple[float, float, float]:
    return (float(v[0]), float(v[1]), float(v[2]))


def firmware_config(scn: Scenario, calibration: Calibration | None = None,
                    sensors: ResolvedSensors | None = None) -> FirmwareConfig:
    """The firmware's configuration: the scenario's firmware section and the calibration file (by default the
    one :func:`calibration_for` makes with the scenario's seed); ``sensors``: the run's merged presets (the fitted
    units' ranges; default: merged here)."""
    if calibration is None:
        calibration = calibration_for(scn)
    fw = scn.firmware
    spec = spec_sheet_for(scn).config_fields()
    if fw.psns.sigma_deg is not None:
        spec["psns_sigma_deg"] = fw.psns.sigma_deg
    gnss_uart = scn.fpga.routing.get("gnss", "uart3")
    # the slower of the receiver's line and the DSP UART paces the bytes (the FPGA forwards cut-through)
    gnss_bauds = [b for b in (scn.fpga.uarts[gnss_uart].baud if gnss_uart in scn.fpga.uarts else None,
                              scn.links.gnss.baud) if b]
    psns_uart = scn.fpga.routing.get("psns", "uart2")
    psns_enabled = fw.psns.enabled if fw.psns.enabled is not None else scn.links.psns is not None
    return FirmwareConfig(
        clock_hz=scn.dsp.clock_hz,
        imu_rate_hz=scn.sensors.imu.rate_hz,
        gyro_output=scn.sensors.imu.output,
        gyro_counter_step=round(2000 / scn.sensors.imu.rate_hz),
        # the fitted units' measurement ranges (a property of the configured variant, like the output and the rate;
        # no error figure): words beyond them are refused (D-5.46)
        gyro_range_dps=gyro_errors(scn, sensors).range_dps,
        accel_range_g=_vec3(accel_errors(scn, sensors).range_g),
        coning_samples=fw.coning_samples,
        kf_predict_every=fw.kf_predict_every,
        output_rate_hz=fw.output_rate_hz,
        nmea_sentences=tuple(fw.nmea.sentences),
        nmea_rate_hz=fw.nmea.rate_hz,
        nmea_attitude_rate_hz=fw.nmea.attitude_rate_hz,
        nmea_talker=fw.nmea.talker,
        text_rate_hz=fw.text_rate_hz,
        # links.host_nmea without a route of its own shares UART0 (the FPGA demultiplexes it: emulator.devices.fpga)
        nmea_uart=int(scn.fpga.routing.get("host_nmea", "uart0")[-1]) if scn.links.host_nmea is not None else 0,
        align_time_s=fw.alignment.time_s,
        alignment_heading=fw.alignment.heading_source,
        psns_align_timeout_s=fw.alignment.psns_timeout_s,
        psns_heading_sigma_deg=fw.alignment.psns_heading_sigma_deg,
        fine_align_time_s=fw.alignment.fine_time_s,
        initial_heading_deg=fw.alignment.heading_deg,
        initial_heading_sigma_deg=fw.alignment.heading_sigma_deg,
        precision=fw.precision,
        nav_state_precision=fw.nav_state_precision,
        filter=fw.filter,
        **spec,  # the sensors' figures: from the firmware's own spec sheet, never from the world's presets
        gnss_baud=min(gnss_bauds) if gnss_bauds else FirmwareConfig.gnss_baud,
        psns_enabled=psns_enabled,
        # an EMIFA UART core has no line baud of its own: the firmware's default line then dates the frames
        psns_baud=scn.fpga.uarts[psns_uart].baud or FirmwareConfig.psns_baud,
        psns_dop_min=fw.psns.dop_min,
        psns_quality_max=fw.psns.quality_max,
        psns_min_sun_elevation_deg=fw.psns.min_sun_elevation_deg,
        psns_gate_chi2=fw.psns.gate_chi2,
        camera=_camera(scn, calibration),
        compass_mountings=_compass_mountings(scn, calibration),
        mag_hard_iron_nt=calibration.magnetometer.hard_iron_nt,
        mag_soft_iron=calibration.magnetometer.soft_iron,
        initial_misalignment_deg=(fw.alignment.misalignment_deg[0], fw.alignment.misalignment_deg[1],
                                  fw.alignment.misalignment_deg[2]),
        variants=variant_params(fw.variants, _plugin_params(scn)),
    )


def build_firmware(scn: Scenario, calibration: Calibration | None = None,
                   sensors: ResolvedSensors | None = None) -> FirmwareProtocol:
    """The firmware the virtual DSP hosts for this scenario (``firmware.implementation``: this package's or a
    ``psns_hil.firmware`` plugin's), configured from its calibration file (``sensors``: :func:`firmware_config`)."""
    register_plugins((scn.firmware.filter,), (scn.firmware.implementation,))
    try:
        factory = FIRMWARE_IMPLEMENTATIONS[scn.firmware.implementation]
    except KeyError:
        raise ScenarioError(f"firmware.implementation: {scn.firmware.implementation!r} is not registered") from None
    return factory(firmware_config(scn, calibration, sensors))
