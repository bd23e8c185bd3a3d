"""The resolved scenario: a validated scenario with every sensor preset merged and every port's URL parsed, once.

A scenario file names presets and URLs; the run needs figures and parsed links. :func:`resolve_scenario` turns the
one into the other a single time per run (issue 42, item 5; decision D-11.R1 in docs/decisions/house.md): each
sensor's preset (``emulator/presets/<kind>.yaml``) is loaded and the scenario's overrides merged on top
(:class:`MergedPreset`), and each external port's URL (and each ``dsp.external.uarts`` URL), confined to the
scenario's directory, is parsed by the links package's one parser into a
:class:`~emulator.links.LinkUrl` (:class:`ResolvedPort`). The assembly (:mod:`emulator.assembly`), the sensor
models and the calibration writer (through :func:`emulator.devices.sensors.installed_unit`), the firmware's
configuration (:mod:`emulator.dsp.firmware_setup`) and ``psns-hil validate --effective`` read this object; none of
them merges a preset or parses a URL again.

The per-kind resolvers (:func:`resolve_sensor`) are what a function of :mod:`emulator.devices.sensors` calls when
it is given no resolved figures (a test building one sensor's configuration from a scenario).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

from ..links import LinkUrl, parse_link_url
from .paths import confined_link_url
from .presets import merged, preset
from .runtime_schema import LinkSpec
from .schema import Scenario
from .sensor_schema import CameraSpec, CompassSpec, MagnetometerSpec, Sensors, preset_of

__all__ = [
    "SENSOR_KINDS",
    "MergedPreset",
    "ResolvedPort",
    "ResolvedScenario",
    "ResolvedSensors",
    "effective_routing",
    "port_specs",
    "resolve_ports",
    "resolve_scenario",
    "resolve_sensor",
    "resolve_sensors",
    "run_mode",
]

#: the sensors that take a preset, in the order they are resolved
SENSOR_KINDS = ("imu", "gnss", "camera", "compass", "magnetometer")


@dataclass(frozen=True)
class MergedPreset:
    """One sensor's figures: preset ``preset`` of ``kind`` with the scenario's overrides applied (``values``)."""

    kind: str
    preset: str
    #: the preset's figures with every override the scenario gives (read-only view; nested values are not copied
    #: again by readers and must not be changed)
    values: Mapping[str, Any]

    def as_dict(self) -> dict[str, Any]:
        return {"preset": self.preset, **_plain(self.values)}


@dataclass(frozen=True)
class ResolvedSensors:
    """The merged presets of every sensor kind (:data:`SENSOR_KINDS`); a sensor the scenario does not fit holds
    its default's figures (the installed unit draws every section)."""

    imu: MergedPreset
    gnss: MergedPreset
    camera: MergedPreset
    compass: MergedPreset
    magnetometer: MergedPreset

    def of(self, kind: str) -> MergedPreset:
        out: MergedPreset = getattr(self, kind)
        return out

    def as_dict(self) -> dict[str, Any]:
        return {k: self.of(k).as_dict() for k in SENSOR_KINDS}


@dataclass(frozen=True)
class ResolvedPort:
    """One external port: the scenario's entry and its URL, confined (zenoh ``auth=`` / ``config=`` files,
    :func:`~emulator.scenario.paths.confined_link_url`) and parsed."""

    name: str
    spec: LinkSpec
    url: LinkUrl

    @property
    def scheme(self) -> str:
        return self.url.scheme

    @property
    def bound_out(self) -> bool:
        """The modelled sensor's stream goes out on a real port (``direction: out | tee``)."""
        return self.spec.direction != "in" and self.url.scheme != "mem"

    def as_dict(self) -> dict[str, Any]:
        return {"url": self.url.url, "scheme": self.url.scheme, "target": self.url.target,
                "options": dict(self.url.options), "baud": self.spec.baud, "mode": self.spec.mode,
                "queue_bytes": self.spec.queue_bytes, "device_baud": self.spec.device_baud,
                "device_mode": self.spec.device_mode, "direction": self.spec.direction}


@dataclass(frozen=True)
class ResolvedScenario:
    """One run's configuration, resolved once (see the module docstring).

    ``scenario`` is the scenario the run is built from (after the envelope's draw, when it has one: the
    :func:`emulator.assembly.build.resolve_run` that makes this object applies it first); ``seed`` the run's seed;
    ``mode`` its time mode."""

    scenario: Scenario
    seed: int
    mode: str
    ports: Mapping[str, ResolvedPort]
    external_uarts: Mapping[str, LinkUrl]
    sensors: ResolvedSensors
    routing: Mapping[str, str]
    #: the envelope's draws for this seed (None without an envelope preset) and the keys the scenario pinned
    envelope_draws: Mapping[str, Any] | None = None
    envelope_pinned: tuple[str, ...] = field(default=())

    def as_dict(self) -> dict[str, Any]:
        """The resolved values as plain JSON data (``psns-hil validate --effective``)."""
        return {
            "scenario": self.scenario.name,
            "seed": self.seed,
            "mode": self.mode,
            "ports": {k: p.as_dict() for k, p in self.ports.items()},
            "external_uarts": {k: {"url": u.url, "scheme": u.scheme, "target": u.target, "options": dict(u.options)}
                               for k, u in self.external_uarts.items()},
            "routing": dict(self.routing),
            "sensors": self.sensors.as_dict(),
            "envelope": None if self.envelope_draws is None
            else {"draws": _plain(self.envelope_draws), "pinned": list(self.envelope_pinned)},
        }


def _plain(v: Any) -> Any:
    """``v`` as plain JSON data (mappings to dicts, tuples to lists)."""
    if isinstance(v, Mapping):
        return {str(k): _plain(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_plain(x) for x in v]
    return v


# -- ports ---------------------------------------------------------------------------------------------------------
def port_specs(scn: Scenario) -> dict[str, LinkSpec]:
    """The scenario's external ports that are wired (gyro, gnss, host; psns, monitor and host_nmea when given)."""
    specs = {"gyro": scn.links.gyro, "gnss": scn.links.gnss, "host": scn.links.host}
    if scn.links.psns is not None:
        specs["psns"] = scn.links.psns
    if scn.links.monitor is not None:
        specs["monitor"] = scn.links.monitor
    if scn.links.host_nmea is not None:
        specs["host_nmea"] = scn.links.host_nmea
    return specs


def resolve_ports(scn: Scenario) -> dict[str, ResolvedPort]:
    """Each wired port (:func:`port_specs`) with its URL confined and parsed."""
    return {port: ResolvedPort(port, spec, parse_link_url(confined_link_url(spec.url, scn.base_dir)))
            for port, spec in port_specs(scn).items()}


def run_mode(scn: Scenario, ports: Mapping[str, ResolvedPort], requested: str | None = None) -> str:
    """The time mode of a run (:func:`emulator.assembly.ports.resolve_mode` says the rule)."""
    if requested:
        return requested
    if "mode" in scn.model_fields_set:
        return scn.mode
    if any(p.scheme != "mem" for p in ports.values()):
        return "realtime"
    if scn.dsp.external is not None and scn.dsp.external.uarts:  # the DSP outside on ports is a real peer
        return "realtime"
    return "fast"


def effective_routing(scn: Scenario) -> dict[str, str]:
    """``fpga.routing`` as the FPGA applies it: ``links.host_nmea`` without a route of its own shares UART0 with
    the host port (the FPGA demultiplexes the firmware's NMEA sentences from its binary frames; docs/runtime.md 3)."""
    routing = {str(k): str(v) for k, v in scn.fpga.routing.items()}
    if scn.links.host_nmea is not None and "host_nmea" not in routing:
        routing["host_nmea"] = routing.get("host", "uart0")
    return routing


# -- sensors -------------------------------------------------------------------------------------------------------
def _imu(sensors: Sensors) -> MergedPreset:
    imu = sensors.imu
    name = preset_of(sensors, "imu", imu)
    p = preset("imu", name)
    t = imu.temperature
    temp = merged(p.get("temperature", {}), {"warmup_c": t.warmup_c, "warmup_tau_s": t.warmup_tau_s})
    values = {
        **p,
        "gyro": merged(p["gyro"], imu.gyro.model_dump()),
        "accel": merged(p["accel"], imu.accel.model_dump()),
        "lp_filter_hz": float(imu.lp_filter_hz if imu.lp_filter_hz is not None else p.get("lp_filter_hz", 0)),
        "temperature": {"warmup_c": float(temp.get("warmup_c", 0.0)),
                        "warmup_tau_s": float(temp.get("warmup_tau_s", 600.0))},
        "vibration": _vibration(p.get("vibration"), imu.vibration),
    }
    return MergedPreset("imu", name, MappingProxyType(values))


def _vibration(base_preset: Any, v: Any) -> dict[str, Any] | None:
    """The vibration profile ``{psd, axes}`` (the scenario's ``sensors.imu.vibration`` over the IMU preset's), or
    None when there is none or it is disabled."""
    base = dict(base_preset or {})
    # the preset says whether its profile is on when the scenario does not mention vibration (field: off)
    on_by_default = bool(base.pop("enabled", True))
    if not (v.enabled if v is not None else on_by_default):
        return None
    p = merged(base, {} if v is None else {"psd": v.psd, "axes": v.axes})
    if not p.get("psd"):
        return None
    return {"psd": [(float(f), float(g)) for f, g in p["psd"]], "axes": tuple(p.get("axes", (1.0, 1.0, 1.0)))}


def _gnss(sensors: Sensors) -> MergedPreset:
    g = sensors.gnss
    name = preset_of(sensors, "gnss", g)
    p = preset("gnss", name)
    values = {
        **p,
        "errors": merged(p["errors"], g.errors.model_dump()),
        "latency_s": g.latency_s if g.latency_s is not None else float(p.get("latency_s", 0.05)),
        "fix_quality": g.fix_quality if g.fix_quality is not None else int(p.get("fix_quality", 1)),
        "reacquisition_s": g.reacquisition_s if g.reacquisition_s is not None else float(p.get("reacquisition_s", 0.8)),
    }
    return MergedPreset("gnss", name, MappingProxyType(values))


def _camera(sensors: Sensors) -> MergedPreset:
    c = sensors.camera if sensors.camera is not None else CameraSpec()
    name = preset_of(sensors, "camera", sensors.camera)
    p = merged(preset("camera", name), {k: getattr(c, k) for k in (
        "full_well_e", "read_noise_e", "adc_bits", "extinction_ratio", "signal_e", "lens", "noise")})
    if c.focal_length_mm is not None:
        p["focal_length_mm"] = c.focal_length_mm
    o = c.optics  # the lens over the preset's (the envelope's lenses)
    p = merged(p, {k: getattr(o, k) for k in ("principal_point_offset_px", "distortion_k1", "distortion_k2",
                                               "exit_pupil_mm")})
    return MergedPreset("camera", name, MappingProxyType(p))


def _compass(sensors: Sensors) -> MergedPreset:
    c = sensors.compass if sensors.compass is not None else CompassSpec()
    name = preset_of(sensors, "compass", sensors.compass)
    p = merged(preset("compass", name), {k: getattr(c, k) for k in (
        "aop_sigma_deg", "dop_ref", "extinction_ratio", "fov_half_deg")})
    inst = c.installation_error_sigma_deg
    p["installation_error_sigma_deg"] = inst if inst is not None else float(p.get("installation_error_sigma_deg", 0.0))
    p["dop_noise_model"] = c.dop_noise_model or p.get("dop_noise_model", "inverse")
    return MergedPreset("compass", name, MappingProxyType(p))


def _magnetometer(sensors: Sensors) -> MergedPreset:
    c = sensors.magnetometer if sensors.magnetometer is not None else MagnetometerSpec()
    name = preset_of(sensors, "magnetometer", sensors.magnetometer)
    p = merged(preset("magnetometer", name), {k: getattr(c, k) for k in (
        "noise_nt", "hard_iron_nt", "soft_iron_scale", "soft_iron_cross")})
    return MergedPreset("magnetometer", name, MappingProxyType(p))


_RESOLVERS = {"imu": _imu, "gnss": _gnss, "camera": _camera, "compass": _compass, "magnetometer": _magnetometer}


def resolve_sensor(sensors: Sensors, kind: str) -> MergedPreset:
    """One sensor's merged preset (``kind`` one of :data:`SENSOR_KINDS`)."""
    return _RESOLVERS[kind](sensors)


def resolve_sensors(sensors: Sensors) -> ResolvedSensors:
    """Every sensor's merged preset: each preset loaded and merged once."""
    return ResolvedSensors(**{k: resolve_sensor(sensors, k) for k in SENSOR_KINDS})


def resolve_scenario(scn: Scenario, seed: int | None = None, requested_mode: str | None = None,
                     envelope_draws: Mapping[str, Any] | None = None,
                     envelope_pinned: tuple[str, ...] = ()) -> ResolvedScenario:
    """``scn`` resolved (see the module docstring); ``seed`` defaults to the scenario's, ``requested_mode`` is the
    command line's (``--fast`` / ``--realtime``)."""
    ports = resolve_ports(scn)
    ext = scn.dsp.external.uarts if scn.dsp.external is not None else {}
    return ResolvedScenario(
        scenario=scn, seed=scn.seed if seed is None else seed, mode=run_mode(scn, ports, requested_mode),
        ports=MappingProxyType(ports),
        external_uarts=MappingProxyType({u: parse_link_url(confined_link_url(url, scn.base_dir))
                                         for u, url in ext.items()}),
        sensors=resolve_sensors(scn.sensors), routing=MappingProxyType(effective_routing(scn)),
        envelope_draws=envelope_draws, envelope_pinned=tuple(envelope_pinned))
