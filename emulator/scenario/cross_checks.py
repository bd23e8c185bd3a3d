"""Checks across the scenario's sections (faults and expectations against links and sensors).

They need the whole :class:`~emulator.scenario.schema.Scenario`, so they live above it: the loader runs
:func:`cross_check` after validation.
"""

from __future__ import annotations

from typing import Any

from .expectations_schema import HookError, check_hook_path
from .presets import preset
from .schema import Scenario
from .sensor_schema import preset_of

__all__ = ["cross_check", "link_names"]


def link_names(scn: Scenario) -> list[str]:
    """The links a run of ``scn`` taps (the names of the summary's link table)."""
    names = ["gyro", "gnss", "host"]
    if scn.links.psns is not None:
        names.append("psns")
    if scn.links.monitor is not None:
        names.append("monitor")
    if scn.links.host_nmea is not None:
        names.append("host_nmea")
    return [*names, "uart0", "uart1", "uart2", "uart3"]


def has_heading_source(scn: Scenario) -> bool:
    """The scenario carries a heading source the firmware can keep heading from: a polarization camera or a
    multi-unit compass on the ``psns`` link (the groups of a consistency check then include ``heading``)."""
    sensors = scn.sensors
    if "psns" not in link_names(scn):
        return False
    compass = sensors.compass is not None and sensors.compass.enabled
    camera = (sensors.camera is not None and sensors.camera.enabled) or (sensors.camera is None and not compass)
    return bool(camera or compass)


def cross_check(scn: Scenario, environment: bool = True) -> list[tuple[tuple[Any, ...], str]]:
    """Problems that involve several sections; each ``(field path, message)``. Empty when all is well.

    ``environment``: also what the run needs from this machine (referenced files, serial devices)."""
    issues: list[tuple[tuple[Any, ...], str]] = []
    dur = scn.duration_s
    links = link_names(scn)
    sensors = scn.sensors
    has_camera = "psns" in links and ((sensors.camera is not None and sensors.camera.enabled)
                                      or (sensors.camera is None and not (sensors.compass and sensors.compass.enabled)))
    has_compass = "psns" in links and sensors.compass is not None and sensors.compass.enabled
    for i, f in enumerate(scn.faults):
        kind = f.kind
        spec = f.spec
        loc = ("faults", i, kind)
        if spec.start_s >= dur:
            issues.append(((*loc, "start_s"), f"{kind} starts at {spec.start_s:g} s, at or after the end of the "
                                               f"run ({dur:g} s)"))
        elif spec.duration_s is not None and spec.start_s + spec.duration_s > dur + 1e-9:
            issues.append(((*loc, "duration_s"),
                           f"{kind} ends at {spec.start_s + spec.duration_s:g} s, after the end of the run "
                           f"({dur:g} s); omit duration_s to last until the end"))
        target = getattr(spec, "link", None)
        if target is not None and target not in links:
            issues.append(((*loc, "link"), _unknown_link(target, links)))
        if kind.startswith("gnss_"):
            if not sensors.gnss.enabled:
                issues.append((loc, f"{kind} needs the GNSS receiver (sensors.gnss.enabled is false)"))
            elif sensors.gnss.recorded is not None:
                issues.append((loc, f"{kind} needs the modelled GNSS receiver, not a recorded file"))
        if kind.startswith("psns_"):
            if "psns" not in links:
                issues.append((loc, f"{kind} needs a polarization sensor; the scenario has no links.psns"))
            elif kind == "psns_unit_blocked" and spec.units is not None and not has_compass:  # type: ignore[attr-defined]
                issues.append(((*loc, "units"), "units are compass units; a camera is blocked as a whole "
                                                 "(omit units)"))
            elif kind in ("psns_cloud_cover", "psns_sun_occluded") and has_camera and sensors.camera is not None \
                    and sensors.camera.recorded is not None:
                issues.append((loc, f"{kind} changes the modelled sky; the camera reads recorded images"))
        if kind.startswith("imu_") and not scn.links.gyro.modelled and \
                (kind == "imu_dropped_datagrams" or getattr(spec, "sensor", "") == "gyro"):
            issues.append((loc, f"{kind} acts on the STIM210 model; links.gyro is an external endpoint"))
        if kind == "fpga_channel_stall":
            ch = spec.channel  # type: ignore[attr-defined]
            if ch == "mag" and (sensors.magnetometer is None or not sensors.magnetometer.enabled):
                issues.append(((*loc, "channel"), "channel mag needs sensors.magnetometer"))
            if ch in ("host", "gnss", "psns") and ch not in scn.fpga.routing:
                issues.append(((*loc, "channel"), f"{ch} is not routed (fpga.routing)"))
            if ch == "psns" and "psns" not in links:
                issues.append(((*loc, "channel"), "the scenario has no links.psns"))
    issues.extend(_confined_files(scn))
    for i, e in enumerate(scn.expectations):
        kind = e.kind
        body = getattr(e, kind)
        loc = ("expectations", i, kind)
        if kind == "link" and body.name not in links:
            issues.append(((*loc, "name"), _unknown_link(body.name, links)))
        if kind == "consistency":
            from .consistency_schema import STATE_GROUPS, asked_groups, min_runs

            groups = asked_groups(body.groups, has_heading_source(scn), body.include_heading)
            dof = 1 if body.measurements else min(STATE_GROUPS[g] for g in groups)
            need = min_runs(body.confidence, dof)
            if body.runs < need:
                issues.append(((*loc, "runs"), f"{body.runs} runs are too few for {body.confidence:.0%} confidence "
                               f"on the {dof}-dof group(s) asked ({', '.join(groups)}; heading is added wherever the "
                               f"scenario has a camera or compass, include_heading: false to leave it out): need "
                               f">= {need}"))
        if kind == "psns" and not has_camera:
            issues.append((loc, "a psns expectation measures the solar vectors the firmware solves from the "
                                "polarization camera; the scenario has no camera (sensors.camera with links.psns)"))
        if kind == "python":
            try:
                check_hook_path(scn.base_dir, body.file)  # confined and present; never imported here
            except HookError as exc:
                issues.append(((*loc, "file"), f"python hook: {exc}"))
    issues += _devices_and_links(scn)
    issues += _vibration(scn)
    issues += _files_and_ports(scn, environment)
    return issues


def _vibration(scn: Scenario) -> list[tuple[tuple[Any, ...], str]]:
    """A vibration PSD's frequencies increase strictly and end at or below the IMU's Nyquist frequency (the world
    draws it at the IMU's trigger rate); an enabled vibration without a PSD needs one from the IMU preset."""
    imu = scn.sensors.imu
    v = imu.vibration
    if v is None or not v.enabled:
        return []
    loc = ("sensors", "imu", "vibration", "psd")
    if v.psd is None:
        name = preset_of(scn.sensors, "imu", imu)
        if not preset("imu", name).get("vibration"):
            return [(loc, f"vibration needs a psd: the IMU preset {name!r} has none "
                          "(give psd: [[f_hz, g2_per_hz], ...], or enabled: false)")]
        return []
    issues: list[tuple[tuple[Any, ...], str]] = []
    nyq = imu.rate_hz / 2.0
    for i in range(1, len(v.psd)):
        if v.psd[i][0] <= v.psd[i - 1][0]:
            issues.append(((*loc, i, 0), f"PSD frequencies must increase: {v.psd[i][0]:g} Hz follows "
                                         f"{v.psd[i - 1][0]:g} Hz"))
    for i, (f, _g) in enumerate(v.psd):
        if f > nyq:
            issues.append(((*loc, i, 0), f"{f:g} Hz is beyond the IMU's Nyquist frequency {nyq:g} Hz "
                                         f"(sensors.imu.rate_hz {imu.rate_hz:g} Hz); allowed range (0, {nyq:g}] Hz"))
    return issues


def _devices_and_links(scn: Scenario) -> list[tuple[tuple[Any, ...], str]]:
    """Every modelled polarization sensor needs ``links.psns`` (without it the run silently leaves it out), and a
    simulated ``links.psns`` needs a sensor to feed it."""
    issues: list[tuple[tuple[Any, ...], str]] = []
    s = scn.sensors
    psns = scn.links.psns
    for name, spec in (("camera", s.camera), ("compass", s.compass)):
        if spec is not None and spec.enabled and psns is None:
            issues.append((("sensors", name), f"a {name} is modelled but the scenario has no links.psns, so the run "
                                              f"would leave it out; add links: {{psns: {{url: mem://psns}}}} or set "
                                              f"sensors.{name}.enabled: false"))
    if psns is not None and psns.modelled:
        camera_off = s.camera is not None and not s.camera.enabled
        compass_on = s.compass is not None and s.compass.enabled
        if camera_off and not compass_on:
            issues.append((("links", "psns"), "links.psns is simulated (mem://) but no polarization sensor is "
                                              "modelled (sensors.camera.enabled is false, no compass): nothing "
                                              "would send on it; remove links.psns or enable a sensor"))
    issues += _port_directions(scn)
    issues += _nmea_rates(scn)
    return issues


def _nmea_rates(scn: Scenario) -> list[tuple[tuple[Any, ...], str]]:
    """The firmware writes NMEA on IMU ticks: each NMEA rate must divide the IMU rate; ``links.host_nmea`` needs
    sentences to carry (its UART: its own route in fpga.routing, or UART0 shared with the host port)."""
    issues: list[tuple[tuple[Any, ...], str]] = []
    # without a route of its own links.host_nmea shares UART0 with the host port: the FPGA demultiplexes it
    if scn.links.host_nmea is not None and not scn.firmware.nmea.sentences and not scn.firmware.text_rate_hz:
        issues.append((("links", "host_nmea"), "links.host_nmea carries the firmware's NMEA output, but "
                                               "firmware.nmea.sentences is empty and firmware.text_rate_hz 0: "
                                               "nothing would be sent"))
    text = scn.firmware.text_rate_hz
    if text:
        r = scn.firmware.output_rate_hz / text
        if r < 1 or abs(r - round(r)) > 1e-9:
            issues.append((("firmware", "text_rate_hz"), f"must divide output_rate_hz "
                                                         f"({scn.firmware.output_rate_hz:g} Hz): the text is written "
                                                         "with a NAV_SOLUTION frame"))
    imu = scn.sensors.imu.rate_hz
    for name in ("rate_hz", "attitude_rate_hz"):
        r = imu / getattr(scn.firmware.nmea, name)
        if r < 1 or abs(r - round(r)) > 1e-9:
            issues.append((("firmware", "nmea", name), f"must divide the IMU rate ({imu:g} Hz): the firmware "
                                                       f"writes NMEA on IMU ticks"))
    return issues


#: ports a modelled sensor drives, which therefore can be bound out (direction out / tee)
SENSOR_PORTS = ("gyro", "gnss", "psns")


def _port_directions(scn: Scenario) -> list[tuple[tuple[Any, ...], str]]:
    """``direction: out | tee`` needs a sensor port with a real endpoint (docs/runtime.md, "Sensor ports out")."""
    from ..links import parse_link_url

    issues: list[tuple[tuple[Any, ...], str]] = []
    for port in ("gyro", "gnss", "psns", "host", "monitor", "host_nmea"):
        spec = getattr(scn.links, port, None)
        if spec is None or spec.direction == "in":
            continue
        loc = ("links", port, "direction")
        if port not in SENSOR_PORTS:
            issues.append((loc, f"links.{port} is not a sensor port: only {', '.join(SENSOR_PORTS)} can be bound "
                                f"out (direction: out or tee); remove the direction"))
        elif (scheme := parse_link_url(spec.url).scheme) == "mem":
            issues.append((loc, f"direction: {spec.direction} binds the modelled sensor's stream to a real port, "
                                f"but links.{port}.url is mem:// (in-process); use pty://, serial:// or zenoh://"))
        elif scheme == "can":
            issues.append((loc, f"links.{port}: a sensor stream cannot go out on can:// (it carries the "
                                f"navigation solution only)"))
    return issues


def _files_and_ports(scn: Scenario, environment: bool) -> list[tuple[tuple[Any, ...], str]]:
    """Referenced files and serial devices exist; no two ports share a pty name or a serial device."""
    from pathlib import Path

    from ..errors import RecordingError
    from ..links import parse_link_url
    from .paths import PathNotAllowed, confine, confined_glob, read_frame_index

    issues: list[tuple[tuple[Any, ...], str]] = []

    def path(name: str) -> Path:
        p = Path(name)
        return p if p.is_absolute() or scn.base_dir is None else Path(scn.base_dir) / p

    s = scn.sensors
    files: list[tuple[tuple[Any, ...], str | None]] = [
        (("sensors", "imu", "recorded", "file"), s.imu.recorded.file if s.imu.recorded else None),
        (("sensors", "gnss", "recorded", "file"), s.gnss.recorded.file if s.gnss.recorded else None),
        (("sensors", "camera", "recorded", "index"),
         s.camera.recorded.index if s.camera is not None and s.camera.recorded is not None else None),
    ]
    def confined(name: str) -> bool:  # a path outside is reported by _confined_files, and never looked at here
        try:
            confine(scn.base_dir, name)
        except PathNotAllowed:
            return False
        return True

    for loc, name in files if environment else []:
        if name is None or not confined(name):
            continue
        if not path(name).is_file():
            issues.append((loc, f"no such file: {path(name)}"))
        elif loc[1] == "camera":
            try:  # every entry confined, as the camera will (no existence oracle: emulator.scenario.paths)
                read_frame_index(path(name), scn.base_dir)
            except RecordingError as exc:
                issues.append((loc, str(exc)))
    if environment and s.camera is not None and s.camera.recorded is not None and s.camera.recorded.files is not None \
            and confined(s.camera.recorded.files):
        pattern = s.camera.recorded.files
        try:  # every match confined before anything behind it is looked at
            if not confined_glob(scn.base_dir, pattern, "camera frame"):
                issues.append((("sensors", "camera", "recorded", "files"), f"no file matches {path(pattern)}"))
        except PathNotAllowed as exc:
            issues.append((("sensors", "camera", "recorded", "files"), str(exc)))
    seen: dict[tuple[str, str], str] = {}
    for port in ("gyro", "gnss", "psns", "host", "monitor", "host_nmea"):
        spec = getattr(scn.links, port, None)
        if spec is None:
            continue
        u = parse_link_url(spec.url)
        if u.scheme not in ("pty", "serial"):
            continue
        if environment and u.scheme == "serial" and not Path(u.target).exists():
            issues.append((("links", port, "url"), f"no such serial device: {u.target}"))
        key = (u.scheme, u.target)
        if key in seen:
            what = "pty name" if u.scheme == "pty" else "serial device"
            issues.append((("links", port, "url"), f"links.{port} uses the same {what} {u.target!r} as "
                                                   f"links.{seen[key]}; every port needs its own"))
        else:
            seen[key] = port
    ext = scn.dsp.external.uarts if scn.dsp.external is not None else {}
    for uname, url in ext.items():  # the DSP outside: its UARTs' ports (docs/runtime.md, DSP out)
        u = parse_link_url(url)
        if u.scheme not in ("pty", "serial"):
            continue
        loc = ("dsp", "external", "uarts", uname)
        if environment and u.scheme == "serial" and not Path(u.target).exists():
            issues.append((loc, f"no such serial device: {u.target}"))
        key = (u.scheme, u.target)
        if key in seen:
            what = "pty name" if u.scheme == "pty" else "serial device"
            other = seen[key] if seen[key].startswith("dsp.") else f"links.{seen[key]}"
            issues.append((loc, f"dsp.external.uarts.{uname} uses the same {what} {u.target!r} as {other}; "
                                "every port needs its own"))
        else:
            seen[key] = f"dsp.external.uarts.{uname}"
    return issues


def _confined_files(scn: Scenario) -> list[tuple[tuple[Any, ...], str]]:
    """Every file a scenario names must lie in the scenario's directory (:mod:`emulator.scenario.paths`): recorded
    data, a lockstep firmware, a link's ``auth=`` and ``config=`` files."""
    from .paths import PathNotAllowed, confine, confined_link_url

    s = scn.sensors
    named: list[tuple[tuple[Any, ...], str | None]] = []
    if s.imu.recorded is not None:
        named.append((("sensors", "imu", "recorded", "file"), s.imu.recorded.file))
    if s.gnss.recorded is not None:
        named.append((("sensors", "gnss", "recorded", "file"), s.gnss.recorded.file))
    cam = getattr(s, "camera", None)
    if cam is not None and cam.recorded is not None:
        named.append((("sensors", "camera", "recorded", "index"), cam.recorded.index))
        named.append((("sensors", "camera", "recorded", "files"), cam.recorded.files))
    ext = scn.dsp.external
    lock = ext.lockstep if ext is not None else None
    if lock is not None:  # a foreign firmware's library or program (docs/icd.md section 10): never loaded here
        if lock.library is not None:
            named.append((("dsp", "external", "lockstep", "library"), lock.library))
        if lock.command is not None:
            named.append((("dsp", "external", "lockstep", "command", 0), lock.command[0]))
    out = []
    for loc, name in named:
        if name is None:
            continue
        what = "lockstep firmware" if loc[:3] == ("dsp", "external", "lockstep") else "recorded file"
        try:
            confine(scn.base_dir, name, what)
        except PathNotAllowed as exc:
            out.append((loc, str(exc)))
    urls: list[tuple[tuple[Any, ...], str]] = [(("links", port, "url"), spec.url) for port in
                                               ("gyro", "gnss", "psns", "host", "monitor", "host_nmea")
                                               if (spec := getattr(scn.links, port, None)) is not None]
    urls += [(("dsp", "external", "uarts", u), url) for u, url in (ext.uarts.items() if ext is not None else ())]
    for loc, url in urls:  # zenoh auth=FILE and config=FILE (decision D-7.32)
        try:
            confined_link_url(url, scn.base_dir)
        except PathNotAllowed as exc:
            out.append((loc, str(exc)))
    return out


def _unknown_link(name: str, links: list[str]) -> str:
    import difflib

    close = difflib.get_close_matches(name, links, n=1, cutoff=0.5)
    hint = f"; did you mean {close[0]!r}?" if close else ""
    return f"no link {name!r} in this scenario (links: {', '.join(links)}){hint}"
