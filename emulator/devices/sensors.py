"""Build the sensor devices of a scenario (merged presets -> error models -> devices).

:func:`build_sensors` is the assembly's single call site (docs/architecture.md, section "Firmware
interface"). It creates every sensor whose port is wired in-process (an ``internal`` link end) and the
FPGA-sampled devices (accelerometers, magnetometer), from the scenario's ``sensors`` section and each sensor's
merged preset (its named preset, ``emulator/presets/*.yaml``, with the scenario's overrides applied:
:mod:`emulator.scenario.resolved`), and reads a recorded file instead of its model when ``recorded:`` is given.

Every function here takes ``sensors``, the run's :class:`~emulator.scenario.resolved.ResolvedSensors` (merged once
per run); without it, it merges the one preset it needs itself (a caller building one sensor's configuration).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from protocols.constants import DEG

from ..errors import ScenarioError
from ..links.base import Link
from ..scenario.resolved import MergedPreset, ResolvedSensors, resolve_sensor, resolve_sensors
from ..scenario.schema import Scenario
from ..world.sky import SkyModel, sky_from_spec
from ..world.sun import SunModel
from ..world.trajectory import Trajectory
from ..world.vibration import VibrationModel
from .base import device_rng
from .camera import (
    IMX250MZR_NX,
    IMX250MZR_NY,
    CameraConfig,
    PolarizationCamera,
    PolarizationCameraModel,
    mounting_matrix,
)
from .camera.optics import SensorDefects
from .camera.spectral import WireGrid, effective_extinction_ratio
from .compass import (
    CompassConfig,
    CompassModel,
    PolarizationCompass,
    default_mountings,
    mountings_from_directions,
    perturbed_mountings,
    turned_about_view_rays,
)
from .gnss import GnssConfig, GnssErrors, GnssGlitch, GnssOutage, GnssReceiver
from .gnss_environment import ENVIRONMENTS, GnssEnvironmentProcess, environment_errors
from .imu import AccelErrors, AnalogAccelerometers, GyroErrors, ImuTemperature, ImuTruthTap, Stim210Gyro
from .imu.stim300 import Stim300Imu
from .magnetometer import MagConfig, Magnetometer, soft_iron_matrix

__all__ = [
    "InstalledUnit",
    "SensorSet",
    "accel_errors",
    "build_sensors",
    "build_sky",
    "build_sun",
    "build_vibration",
    "camera_config",
    "camera_extinction_ratio",
    "compass_config",
    "gnss_config",
    "gyro_errors",
    "imu_temperature",
    "imu_vibration",
    "installed_unit",
    "mag_config",
]



@dataclass(frozen=True)
class InstalledUnit:
    """The unit as installed: the world's truth of what a bench calibration measures, drawn once per run and shared
    by the sensor models (:func:`build_sensors`) and the calibration writer
    (:func:`emulator.dsp.firmware_setup.calibration_for`), so both see the same installation, by construction.

    ``camera``: the lens, the mounting and the polarizer defects; ``compass``: each unit's installed mounting (the
    nominal layout turned by a draw of the installation error, stream ``compass_mount``); ``magnetometer``: the hard
    and soft iron. A section the scenario has not fitted holds the default sensor's truth (unused)."""

    camera: CameraConfig
    compass: CompassConfig
    magnetometer: MagConfig


def installed_unit(scn: Scenario, seed: int | None = None, sensors: ResolvedSensors | None = None) -> InstalledUnit:
    """Draw the installed unit of ``scn`` with ``seed`` (default: the scenario's)."""
    seed = scn.seed if seed is None else seed
    return InstalledUnit(camera=camera_config(scn, seed, sensors),
                         compass=compass_config(scn, device_rng(seed, "compass_mount"), sensors),
                         magnetometer=mag_config(scn, sensors))


@dataclass
class SensorSet:
    """The sensor models of one run (None where the port is driven from outside or the sensor is absent)."""

    gyro: Stim210Gyro | None
    accel: AnalogAccelerometers
    gnss: Any | None
    psns: PolarizationCamera | None = None
    compass: PolarizationCompass | None = None
    mag: Magnetometer | None = None
    sky: SkyModel | None = None
    sun: SunModel | None = None
    extra: list[Any] = field(default_factory=list)

    def start(self) -> None:
        """Start the devices that schedule themselves (everything not driven by an FPGA trigger)."""
        for dev in (self.gnss, self.psns, self.compass, *self.extra):
            if dev is not None:
                dev.start()

    def counters(self) -> dict[str, int | None]:
        """Frames each device has sent (for the summary)."""
        return {
            "gyro_datagrams": self.gyro.datagrams_sent if self.gyro else None,
            "gnss_epochs": self.gnss.epochs_sent if self.gnss else None,
            "gnss_pps_pulses": getattr(self.gnss, "pps_pulses", None),
            # what a host sent the receiver (UBX polls answered, CFG sets acknowledged / refused, other input)
            "gnss_host_polls": getattr(self.gnss, "host_polls", None),
            "gnss_host_acks": getattr(self.gnss, "host_acks", None),
            "gnss_host_naks": getattr(self.gnss, "host_naks", None),
            "gnss_host_ignored": getattr(self.gnss, "host_ignored", None),
            "psns_frames": self.psns.frames_sent if self.psns else None,
            "compass_frames": self.compass.frames_sent if self.compass else None,
            "mag_samples": self.mag.samples if self.mag else None,
        }


def _enu3(v: Sequence[float]) -> tuple[float, float, float]:
    """A validated 3-vector (east, north, up) of the scenario as a tuple."""
    return (v[0], v[1], v[2])


def _dataclass_from(cls: type, values: dict[str, Any]) -> Any:
    obj = cls()
    for k, v in values.items():
        if not hasattr(obj, k):
            raise ValueError(f"{cls.__name__} has no field {k!r}")
        setattr(obj, k, tuple(v) if isinstance(v, list) else v)
    return obj


def _merged(scn: Scenario, kind: str, sensors: ResolvedSensors | None) -> Mapping[str, Any]:
    """The merged preset of sensor ``kind``: the run's (``sensors``), else merged now for this one sensor."""
    m: MergedPreset = sensors.of(kind) if sensors is not None else resolve_sensor(scn.sensors, kind)
    return m.values


def gyro_errors(scn: Scenario, sensors: ResolvedSensors | None = None) -> GyroErrors:
    return _dataclass_from(GyroErrors, _merged(scn, "imu", sensors)["gyro"])


def accel_errors(scn: Scenario, sensors: ResolvedSensors | None = None) -> AccelErrors:
    return _dataclass_from(AccelErrors, _merged(scn, "imu", sensors)["accel"])


def gyro_lp_filter_hz(scn: Scenario, sensors: ResolvedSensors | None = None) -> float:
    """The STIM210 low-pass setting (-3 dB, Hz; 0 = none): the scenario's, else the IMU preset's."""
    return float(_merged(scn, "imu", sensors)["lp_filter_hz"])


def imu_temperature(scn: Scenario, sensors: ResolvedSensors | None = None) -> ImuTemperature:
    """The IMU temperature profile: the scenario's ``sensors.imu.temperature``, the warm-up from the IMU preset
    where the scenario leaves it out (docs/sensors.md, "IMU temperature")."""
    t = scn.sensors.imu.temperature
    w = _merged(scn, "imu", sensors)["temperature"]
    return ImuTemperature(t.start_c, t.rate_c_per_min, t.cal_c, warmup_c=w["warmup_c"],
                          warmup_tau_s=w["warmup_tau_s"])


def imu_vibration(scn: Scenario, sensors: ResolvedSensors | None = None) -> dict[str, Any] | None:
    """The vibration profile ``{psd, axes}`` of the scenario (its ``sensors.imu.vibration`` over the IMU preset's),
    or None when there is none or it is disabled."""
    prof: dict[str, Any] | None = _merged(scn, "imu", sensors)["vibration"]
    return prof


def build_vibration(scn: Scenario, seed: int, sensors: ResolvedSensors | None = None) -> VibrationModel | None:
    """The world's vibration (:mod:`emulator.world.vibration`) of ``scn``, None without a profile."""
    prof = imu_vibration(scn, sensors)
    if prof is None:
        return None
    return VibrationModel(prof["psd"], prof["axes"], scn.sensors.imu.rate_hz, device_rng(seed, "vibration"))


def gnss_config(scn: Scenario, seed: int | None = None, sensors: ResolvedSensors | None = None) -> GnssConfig:
    """The receiver of ``scn``; ``seed`` (default the scenario's) draws its environment's run (``environment``)."""
    g = scn.sensors.gnss
    p = _merged(scn, "gnss", sensors)
    err = _dataclass_from(GnssErrors, p["errors"])
    env_process = None
    num_sats, hdop = g.num_sats, g.hdop
    if g.environment is not None:
        env = ENVIRONMENTS[g.environment]
        s = scn.seed if seed is None else seed
        env_process = GnssEnvironmentProcess(env, device_rng(s, "gnss_environment"), device_rng(s, "gnss_residuals"))
        # the receiver reports the geometry it solved with, and its errors follow it (DOP law)
        err = environment_errors(env, err, env_process.hdop, g.hdop)
        num_sats, hdop = env_process.num_sats, env_process.hdop
    return GnssConfig(
        rate_hz=g.rate_hz, latency_s=p["latency_s"],
        sentences=tuple(g.sentences), ubx=tuple(g.ubx), talker=g.talker, nmea_version=g.nmea_version,
        geoid_sep_m=g.geoid_sep_m, geoid_sep_field=g.geoid_sep_field,
        fix_quality=p["fix_quality"], reacquisition_s=p["reacquisition_s"],
        num_sats=num_sats, hdop=hdop,
        outages=tuple(GnssOutage(o.start_s, o.duration_s) for o in g.outages),
        glitches=tuple(GnssGlitch(x.start_s, x.duration_s, _enu3(x.offset_enu_m)) for x in g.glitches),
        errors=err, environment=env_process,
    )


def _defect_args(d: dict[str, Any]) -> dict[str, Any]:
    return {k: tuple(v) if isinstance(v, list) else v for k, v in d.items()}


def camera_extinction_ratio(p: Mapping[str, Any]) -> float:
    """The camera's extinction ratio: the scenario's or preset's ``extinction_ratio`` if given (an override), else
    the effective ratio of the preset's ``wire_grid`` under a Rayleigh sky (:mod:`.camera.spectral`)."""
    if p.get("extinction_ratio") is not None:
        return float(p["extinction_ratio"])
    return effective_extinction_ratio(WireGrid(**{k: float(v) for k, v in p["wire_grid"].items()}))


def camera_config(scn: Scenario, seed: int | None = None, sensors: ResolvedSensors | None = None) -> CameraConfig:
    """The camera of ``scn`` (the world's truth); ``seed`` picks the physical sensor's fixed pattern."""
    c = scn.sensors.camera
    if c is None:
        from ..scenario.sensor_schema import CameraSpec

        c = CameraSpec()
    p = _merged(scn, "camera", sensors)  # the preset, the scenario's figures and its lens (the envelope's lenses)
    m = c.mounting
    o = c.optics
    pp = p.get("principal_point_offset_px", (0.0, 0.0))
    return CameraConfig(
        lens=p["lens"], focal_m=p["focal_length_mm"] * 1e-3, fisheye_max_theta=c.fisheye_max_theta_deg * DEG,
        mounting_c_b=mounting_matrix(m.heading_deg, m.pitch_deg, m.roll_deg, m.installation_error_deg),
        full_well_e=p["full_well_e"], read_noise_e=p["read_noise_e"], adc_bits=int(p["adc_bits"]),
        extinction_ratio=camera_extinction_ratio(p), signal_e=p["signal_e"], grid=tuple(c.grid),  # type: ignore[arg-type]
        bin_superpixels=c.bin_superpixels, fidelity=c.fidelity, sun_glare=c.sun_glare_deg * DEG,
        min_sun_elevation=c.min_sun_elevation_deg * DEG, dop_threshold=c.dop_threshold, min_points=c.min_points,
        noise=bool(p.get("noise", True)),
        auto_exposure_target=c.auto_exposure_target, auto_exposure_percentile=c.auto_exposure_percentile,
        cx_px=(IMX250MZR_NX + 1) / 2.0 + pp[0] if pp[0] else None,
        cy_px=(IMX250MZR_NY + 1) / 2.0 + pp[1] if pp[1] else None,
        k1=float(p.get("distortion_k1", 0.0)), k2=float(p.get("distortion_k2", 0.0)),
        exit_pupil_m=p["exit_pupil_mm"] * 1e-3 if p.get("exit_pupil_mm") is not None else None,
        k3=o.distortion_k3, p1=o.tangential_p1, p2=o.tangential_p2, lens_diattenuation_edge=o.radial_diattenuation_edge,
        defects=SensorDefects(**_defect_args({**p.get("defects", {}), **c.defects.model_dump(exclude_none=True)})),
        defect_seed=scn.seed if seed is None else seed,
    )


def compass_config(scn: Scenario, rng: np.random.Generator | None = None,
                   sensors: ResolvedSensors | None = None) -> CompassConfig:
    c = scn.sensors.compass
    if c is None:
        from ..scenario.sensor_schema import CompassSpec

        c = CompassSpec()
    p = _merged(scn, "compass", sensors)
    mounts = default_mountings()
    if c.units is not None:  # a compass with its own unit layout (e.g. the dual-vector study's three sensors)
        mounts = mountings_from_directions([(u.zenith_deg, u.azimuth_deg) for u in c.units])
    inst = p["installation_error_sigma_deg"]
    if inst > 0:
        mounts = perturbed_mountings(mounts, inst * DEG, rng or np.random.default_rng(0))
    if c.aop_offset_deg is not None:  # calibration residual: each unit turned about its view ray (AOP + offset)
        mounts = turned_about_view_rays(mounts, np.asarray(c.aop_offset_deg, dtype=np.float64) * DEG)
    return CompassConfig(mountings=mounts, aop_sigma=p["aop_sigma_deg"] * DEG, dop_ref=p["dop_ref"],
                         extinction_ratio=p["extinction_ratio"], fov_half=p["fov_half_deg"] * DEG,
                         min_sun_elevation=c.min_sun_elevation_deg * DEG, noise=p["aop_sigma_deg"] > 0,
                         dop_noise_model=p["dop_noise_model"],
                         blocked=tuple((tuple(b.units), b.start_s, b.start_s + b.duration_s) for b in c.blocked))


def mag_config(scn: Scenario, sensors: ResolvedSensors | None = None) -> MagConfig:
    c = scn.sensors.magnetometer
    if c is None:
        from ..scenario.sensor_schema import MagnetometerSpec

        c = MagnetometerSpec()
    p = _merged(scn, "magnetometer", sensors)
    return MagConfig(declination_deg=c.declination_deg, inclination_deg=c.inclination_deg,
                     intensity_nt=c.intensity_nt, noise_nt=p["noise_nt"], hard_iron_nt=tuple(p["hard_iron_nt"]),
                     soft_iron=soft_iron_matrix(tuple(p["soft_iron_scale"]), tuple(p["soft_iron_cross"])))


def build_sky(scn: Scenario, seed: int) -> SkyModel:
    return sky_from_spec(scn.sky, device_rng(seed, "sky"))


def build_sun(scn: Scenario) -> SunModel:
    return SunModel(scn.epoch, scn.sky.delta_t_s)


def _path(scn: Scenario, name: str) -> Path:
    """A recorded file's path, confined to the scenario's directory (docs/hostile-input.md)."""
    from ..scenario.paths import confine

    return confine(scn.base_dir, name, "recorded file")


def build_sensors(scn: Scenario, seed: int, traj: Trajectory, internal: dict[str, Link],
                  pps: Callable[[float], None], unit: InstalledUnit | None = None,
                  sensors: ResolvedSensors | None = None) -> SensorSet:
    """Create the sensor models whose ports are wired in-process (``internal`` link ends); ``unit``: the installed
    unit the calibration writer also gets (default: :func:`installed_unit` of ``scn`` and ``seed``); ``sensors``:
    the run's merged presets (default: merged here, once)."""
    from . import recorded

    if sensors is None:
        sensors = resolve_sensors(scn.sensors)
    if unit is None:
        unit = installed_unit(scn, seed, sensors)

    s = scn.sensors
    tap = ImuTruthTap(traj, build_vibration(scn, seed, sensors) if s.imu.recorded is None else None)
    temp = imu_temperature(scn, sensors)
    gyro_src = accel_src = None
    if s.imu.recorded is not None:
        rec = recorded.RecordedImu(_path(scn, s.imu.recorded.file), s.imu.recorded.time_offset_s)
        gyro_src, accel_src = rec.mean_rate, rec.mean_specific_force
    gyro = None
    if "gyro" in internal:
        kw: dict[str, Any] = {"ident": int(s.imu.stim300_datagram, 16)} if s.imu.device == "stim300" else {}
        gyro = (Stim300Imu if s.imu.device == "stim300" else Stim210Gyro)(
            internal["gyro"], tap, device_rng(seed, "gyro"), gyro_errors(scn, sensors),
            fmt=s.imu.format, output=s.imu.output, trigger_rate_hz=s.imu.rate_hz,
            temperature=temp, source=gyro_src, lp_filter_hz=gyro_lp_filter_hz(scn, sensors), **kw)
    accel = AnalogAccelerometers(tap, device_rng(seed, "accel"), accel_errors(scn, sensors), temperature=temp,
                                 source=accel_src, trigger_rate_hz=s.imu.rate_hz)
    gnss: Any = None
    if "gnss" in internal and s.gnss.enabled:
        if s.gnss.recorded is not None:
            gnss = recorded.recorded_gnss(internal["gnss"], _path(scn, s.gnss.recorded.file), s.gnss.recorded.format,
                                          scn.epoch, gnss_config(scn, None, sensors), s.gnss.recorded.time_offset_s,
                                          pps=pps, rng=device_rng(seed, "gnss"))
        else:
            gnss = GnssReceiver(internal["gnss"], traj, scn.epoch, device_rng(seed, "gnss"),
                                gnss_config(scn, seed, sensors), pps=pps)
    sky = sun = None
    camera = compass = None
    want_camera = s.camera is not None and s.camera.enabled
    want_compass = s.compass is not None and s.compass.enabled
    if "psns" in internal and not want_compass and s.camera is None:
        want_camera = True  # a PSNS port with no sensor section: the default camera
    if "psns" in internal and (want_camera or want_compass):
        sky, sun = build_sky(scn, seed), build_sun(scn)
        if want_camera:
            cs = s.camera
            model = PolarizationCameraModel(unit.camera, sky, sun, traj,
                                            device_rng(seed, "psns_camera"))
            src = None
            if cs is not None and cs.recorded is not None:
                r = cs.recorded
                src = recorded.RecordedImages(
                    index=_path(scn, r.index) if r.index else None,
                    files=r.files, rate_hz=r.rate_hz, start_s=r.start_s, shape=(model.cfg.ny, model.cfg.nx),
                    base_dir=scn.base_dir).mosaic_at
            rate = cs.rate_hz if cs is not None else 5.0
            try:
                camera = PolarizationCamera(internal["psns"], model, rate_hz=rate,
                                            exposure_s=(cs.exposure_us if cs else 1000) * 1e-6,
                                            processing_s=(cs.processing_ms if cs else 20.0) * 1e-3,
                                            mosaic_source=src)
            except ValueError as exc:
                raise ScenarioError(f"sensors.camera: {exc}", file=scn.source_file) from exc
        if want_compass:
            cs2 = s.compass
            assert cs2 is not None
            cm = CompassModel(unit.compass, sky, sun, traj,
                              device_rng(seed, "compass"))
            compass = PolarizationCompass(internal["psns"], cm, rate_hz=cs2.rate_hz,
                                          integration_s=cs2.integration_ms * 1e-3,
                                          processing_s=cs2.processing_ms * 1e-3)
    mag = None
    if s.magnetometer is not None and s.magnetometer.enabled:
        mag = Magnetometer(traj, device_rng(seed, "mag"), unit.magnetometer)
    return SensorSet(gyro, accel, gnss, psns=camera, compass=compass, mag=mag, sky=sky, sun=sun)
