"""Map a scenario onto the firmware's build/run-time configuration."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from firmware_model import FirmwareConfig
from firmware_model.attitude import a2mat, yaw_from_heading
from firmware_model.calibration import Calibration, CalibrationError, CameraCalibration, load_calibration
from firmware_model.psns_geometry import CameraGeometry, camera_from_calibration
from firmware_model.registry import (
    BUILTIN_FILTER_PARAMS,
    FIRMWARE_IMPLEMENTATIONS,
    FirmwareProtocol,
    filter_params_model,
)
from firmware_model.spec_sheet import SensorSpecSheet, SpecSheetError
from firmware_model.variants.common import compass_mountings
from firmware_model.variants.params import (
    DualVectorParams,
    FederatedParams,
    KmeansParams,
    ModeManagerParams,
    SunElevationParams,
    VariantParams,
)

from ..devices.base import device_rng
from ..devices.sensors import camera_config
from ..errors import ScenarioError
from ..plugins import PLUGIN_ERRORS, plugin, plugin_names
from ..scenario.schema import Scenario

__all__ = ["SPEC_SHEET_DIR", "build_firmware", "calibration_for", "firmware_config", "register_plugins",
           "spec_sheet_for"]

#: the spec sheets bundled with the firmware (``firmware.spec_sheet: <name>``)
SPEC_SHEET_DIR = Path(__file__).resolve().parents[2] / "firmware_model" / "spec_sheets"

DEG = math.pi / 180.0


def _rotvec_deg(c: np.ndarray) -> tuple[float, float, float]:
    x, y, z = (float(a) for a in np.degrees(Rotation.from_matrix(c).as_rotvec()))
    return x, y, z


def calibration_for(scn: Scenario, seed: int | None = None) -> Calibration:
    """The calibration file the DSP gets (``firmware.calibration``): the camera's truth plus residuals drawn with
    the run's seed, the truth itself, the design values, or the user's file (confined to the scenario's
    directory). This is the one place where the world's truth reaches the firmware, and only through the file."""
    spec = scn.firmware.calibration
    seed = scn.seed if seed is None else seed
    if spec.source == "file":
        assert spec.file is not None
        base = Path(scn.base_dir).resolve() if scn.base_dir is not None else Path.cwd().resolve()
        path = (base / spec.file).resolve()
        if not path.is_relative_to(base):
            raise ScenarioError(f"firmware.calibration.file: {spec.file} is outside the scenario's directory")
        try:
            return load_calibration(path)
        except CalibrationError as exc:
            raise ScenarioError(f"firmware.calibration.file: {exc}") from exc
    if scn.sensors.camera is None:
        return Calibration()
    cc = camera_config(scn, seed)
    m = scn.sensors.camera.mounting
    if spec.source == "nominal":  # the design: the lens drawing and the nominal mount, no bench measurement
        nominal_c_b = a2mat(m.pitch_deg * DEG, m.roll_deg * DEG, yaw_from_heading(m.heading_deg * DEG))
        return Calibration(camera=CameraCalibration(
            projection=cc.lens, nx=cc.nx, ny=cc.ny, pixel_m=cc.pixel_m, focal_m=cc.focal_m,
            boresight_rotvec_deg=_rotvec_deg(nominal_c_b), extinction_ratio=min(cc.extinction_ratio, 1e9)))
    truth = CameraCalibration(
        projection=cc.lens, nx=cc.nx, ny=cc.ny, pixel_m=cc.pixel_m, focal_m=cc.focal_m,
        cx_px=cc.lens_model.cx, cy_px=cc.lens_model.cy, k1=cc.k1, k2=cc.k2, exit_pupil_m=cc.exit_pupil_m,
        boresight_rotvec_deg=_rotvec_deg(cc.mounting_c_b),
        polarizer_deg=tuple(th + b for th, b in zip((0.0, 45.0, 90.0, 135.0),  # type: ignore[arg-type]
                                                     cc.defects.orientation_bias_deg, strict=True)),
        extinction_ratio=min(cc.extinction_ratio, 1e9))
    if spec.source == "perfect":
        return Calibration(camera=truth)
    r = spec.residuals
    rng = device_rng(seed, "calibration")
    err = Rotation.from_rotvec(np.radians(r.boresight_deg * rng.standard_normal(3)))
    c_b = cc.mounting_c_b @ err.as_matrix()
    pp = r.principal_point_px * rng.standard_normal(2)
    return Calibration(camera=replace(
        truth, focal_m=truth.focal_m * (1.0 + r.focal_rel * float(rng.standard_normal())),
        cx_px=float(cc.lens_model.cx + pp[0]), cy_px=float(cc.lens_model.cy + pp[1]),
        k1=truth.k1 + r.distortion_k1 * float(rng.standard_normal()),
        exit_pupil_m=None if truth.exit_pupil_m is None
        else truth.exit_pupil_m * (1.0 + r.exit_pupil_rel * float(rng.standard_normal())),
        boresight_rotvec_deg=_rotvec_deg(c_b),
        polarizer_deg=tuple(a + r.polarizer_deg * float(rng.standard_normal())  # type: ignore[arg-type]
                            for a in truth.polarizer_deg)))


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
    else:
        base = Path(scn.base_dir).resolve() if scn.base_dir is not None else Path.cwd().resolve()
        path = (base / ref).resolve()
        if not path.is_relative_to(base):
            raise ScenarioError(f"firmware.spec_sheet: {ref} is outside the scenario's directory")
        if not path.is_file():
            raise ScenarioError(f"firmware.spec_sheet: {ref}: no such file")
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8"))
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


def _variant_params(scn: Scenario) -> VariantParams:
    """``firmware.variants`` -> :class:`firmware_model.variants.params.VariantParams` (same field names)."""
    v = scn.firmware.variants
    fed = v.federated.model_dump()
    fed["subfilters"] = tuple(fed["subfilters"])
    if fed["initial_attitude_sigma_deg"] is not None:
        fed["initial_attitude_sigma_deg"] = tuple(fed["initial_attitude_sigma_deg"])
    return VariantParams(
        mode_manager=ModeManagerParams(**v.mode_manager.model_dump()),
        dual_vector=DualVectorParams(**v.dual_vector.model_dump()),
        kmeans_3d=KmeansParams(**v.kmeans_3d.model_dump()),
        federated=FederatedParams(**fed),
        sun_elevation=SunElevationParams(**v.sun_elevation.model_dump()),
        plugins=_plugin_params(scn),
    )


def register_plugins() -> None:
    """Enter the ``psns_hil.filters`` and ``psns_hil.firmware`` entry points (:mod:`emulator.plugins`) in the
    firmware's tables (:data:`firmware_model.FILTER_VARIANTS`,
    :data:`firmware_model.registry.FIRMWARE_IMPLEMENTATIONS`). A built-in name is never replaced; what cannot be
    entered is kept in :data:`emulator.plugins.PLUGIN_ERRORS`."""
    from firmware_model.config import FILTER_VARIANTS
    from firmware_model.filters import NavFilter, register_filter
    from firmware_model.registry import register_firmware

    for name in plugin_names("psns_hil.filters"):
        if name in FILTER_VARIANTS:
            if getattr(FILTER_VARIANTS[name], "__module__", "").startswith("firmware_model."):
                PLUGIN_ERRORS.setdefault(("psns_hil.filters", name), f"the name {name!r} is built in; not replaced")
            continue
        cls = plugin("psns_hil.filters", name)
        if cls is None:
            continue
        if not (isinstance(cls, type) and issubclass(cls, NavFilter)):
            PLUGIN_ERRORS[("psns_hil.filters", name)] = "not a firmware_model.filters.NavFilter subclass"
            continue
        register_filter(name)(cls)
    for name in plugin_names("psns_hil.firmware"):
        if name in FIRMWARE_IMPLEMENTATIONS:
            continue
        factory = plugin("psns_hil.firmware", name)
        if callable(factory):
            register_firmware(name, factory)


def _plugin_params(scn: Scenario) -> dict[str, object]:
    """``firmware.params`` of a filter added by entry point, as an instance of the model it declares (validated
    by the scenario schema; a built-in variant's are merged into ``firmware.variants`` there)."""
    name = scn.firmware.filter
    if name in BUILTIN_FILTER_PARAMS:
        return {}
    register_plugins()
    model = filter_params_model(name)
    if model is None:
        return {}
    from pydantic import TypeAdapter

    return {name: TypeAdapter(model).validate_python(scn.firmware.params)}


def _compass_mountings(scn: Scenario):
    """The compass's nominal unit layout as the firmware knows it (no installation error); None: default 9."""
    c = scn.sensors.compass
    if c is None or c.units is None:
        return None
    return compass_mountings([(u.zenith_deg, u.azimuth_deg) for u in c.units])


def firmware_config(scn: Scenario, calibration: Calibration | None = None) -> FirmwareConfig:
    """The firmware's configuration: the scenario's firmware section and the calibration file (by default the
    one :func:`calibration_for` makes with the scenario's seed)."""
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
        coning_samples=fw.coning_samples,
        kf_predict_every=fw.kf_predict_every,
        output_rate_hz=fw.output_rate_hz,
        nmea_sentences=tuple(fw.nmea.sentences),
        nmea_rate_hz=fw.nmea.rate_hz,
        nmea_attitude_rate_hz=fw.nmea.attitude_rate_hz,
        nmea_talker=fw.nmea.talker,
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
        compass_mountings=_compass_mountings(scn),
        initial_misalignment_deg=(fw.alignment.misalignment_deg[0], fw.alignment.misalignment_deg[1],
                                  fw.alignment.misalignment_deg[2]),
        variants=_variant_params(scn),
    )


def build_firmware(scn: Scenario, calibration: Calibration | None = None) -> FirmwareProtocol:
    """The firmware the virtual DSP hosts for this scenario (``firmware.implementation``: this package's or a
    ``psns_hil.firmware`` plugin's), configured from its calibration file."""
    register_plugins()
    try:
        factory = FIRMWARE_IMPLEMENTATIONS[scn.firmware.implementation]
    except KeyError:
        raise ScenarioError(f"firmware.implementation: {scn.firmware.implementation!r} is not registered") from None
    return factory(firmware_config(scn, calibration))
