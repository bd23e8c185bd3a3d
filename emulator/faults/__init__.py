"""Fault injection: the scenario's ``faults:`` section, scheduled on the emulator's clock.

:class:`FaultScheduler` turns every fault of the scenario into an injector bound to the device or
link it acts on, switches it on at ``start_s`` and off at ``start_s + duration_s`` (or at the end
of the run) and writes both moments to ``events.jsonl`` (source ``fault``, events ``fault_start``
and ``fault_end``). Injectors act only through small, explicit capabilities of the devices
(``Stim210Gyro.set_stuck_axis``, ``GnssReceiver.add_outage``, ``VirtualFpga.set_channel_stalled``,
``VirtualDsp.extra_cycles_per_tick``...) and through the links' byte-fault hooks
(:class:`emulator.links.base.ByteFault`, ``Link.faults_in`` / ``faults_out``).

Evidence. While a fault is active its injector counts what it really did: bytes it corrupted or
dropped, epochs sent without a fix, samples it clipped, view rays under a cloud, ticks it loaded.
``fault_end`` carries those counts, and the summary lists them (``summary["faults"]``). A fault
whose effect count stayed at zero never took effect (a saturation limit above every rate the
vehicle reached, a cloud where no sensor looks, a baud error inside the UART tolerance): the run
is then **invalid** (``summary["valid"] = false``, exit code 1), because a test that passes with
a fault that did not fire proves nothing. ``fault_end`` also carries the changes of the
firmware's counters over the window (``firmware``: GNSS updates, PSNS rejections, missing gyro
data...), which show what the fault did downstream.

Directions of link faults are named from the DSP: ``to_dsp`` (sensor -> FPGA -> DSP, host commands)
and ``from_dsp`` (navigation output towards the host, the monitor port). On an external port the
fault sits on the FPGA's end of the cable, on ``uart0..3`` on the DSP's end, so the recorder's
decoders (the link table of the summary) see what the receiver got.

Every random draw comes from ``device_rng(seed, "fault:<index>:<kind>")``: a run is reproducible, and
adding a fault does not change the random numbers of the sensors.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from ..devices.base import EventSink, device_rng
from ..errors import ScenarioError, ScenarioIssue
from ..links.base import LineConfig, Link
from ..scenario.checks_schema import Fault

if TYPE_CHECKING:
    from ..assembly.runner import Emulator

__all__ = ["FaultScheduler", "Injector", "FIRMWARE_COUNTERS"]

DEG = math.pi / 180.0
G_STD = 9.80665
#: firmware counters whose change over a fault's window is reported in ``fault_end``
FIRMWARE_COUNTERS = ("gnss_fixes", "gnss_updates", "psns_frames", "psns_updates", "psns_rejected", "psns_invalid",
                     "compass_frames", "fpga_gyro_missing", "gyro_counter_jumps", "imu_frames", "imu_time_gaps")
_AXES = {"x": 0, "y": 1, "z": 2}


class Injector:
    """One fault bound to its target. Subclasses implement :meth:`on`, :meth:`off` and :meth:`_counts`.

    ``_counts()`` returns cumulative counters of the target; the evidence is their change while the
    fault was active (overridden by injectors that count by themselves). ``effect_keys`` name the
    counts that prove the fault took effect.
    """

    effect_keys: tuple[str, ...] = ()

    def __init__(self, emu: "Emulator", kind: str, spec: Any, index: int, rng: np.random.Generator) -> None:
        self.emu = emu
        self.kind = kind
        self.spec = spec
        self.index = index
        self.rng = rng
        self.active = False
        self.t_on: float | None = None
        self.t_off: float | None = None
        self._c0: dict[str, int] = {}
        self._acc: dict[str, int] = {}

    # -- described by subclasses ---------------------------------------------------------------
    @property
    def target(self) -> str:
        return ""

    def on(self, t: float) -> None:  # noqa: D102
        raise NotImplementedError

    def off(self, t: float) -> None:  # noqa: D102
        raise NotImplementedError

    def _counts(self) -> dict[str, int]:
        return {}

    # -- shared ------------------------------------------------------------------------------------
    def start(self, t: float) -> None:
        self._c0 = self._counts()
        self.on(t)
        self.active = True
        self.t_on = t

    def stop(self, t: float) -> None:
        if not self.active:
            return
        self.off(t)
        c1 = self._counts()
        for k, v in c1.items():
            self._acc[k] = self._acc.get(k, 0) + max(0, int(v) - int(self._c0.get(k, 0)))
        self.active = False
        self.t_off = t

    def evidence(self) -> dict[str, int]:
        return dict(self._acc)

    @property
    def fired(self) -> bool:
        ev = self.evidence()
        return any(ev.get(k, 0) > 0 for k in self.effect_keys)


# ================================================================================ GNSS
def _gnss(emu: "Emulator", kind: str) -> Any:
    rx = getattr(emu.sensors, "gnss", None) if emu.sensors is not None else None
    if rx is None or not hasattr(rx, "add_outage"):
        raise _bind_error(kind, "needs the modelled GNSS receiver on an in-process (mem://) gnss link")
    return rx


class _GnssOutage(Injector):
    effect_keys = ("epochs_without_fix",)

    def __init__(self, *a: Any) -> None:
        super().__init__(*a)
        self.rx = _gnss(self.emu, self.kind)

    @property
    def target(self) -> str:
        return "gnss receiver"

    def on(self, t: float) -> None:
        end = self.spec.end_s(self.emu.scn.duration_s)
        self.rx.add_outage(t, max(end - t, 1e-9))

    def off(self, t: float) -> None:
        pass  # the outage is time-windowed in the receiver; re-acquisition follows it

    def _counts(self) -> dict[str, int]:
        return {"epochs_without_fix": self.rx.no_fix_epochs}


class _GnssGlitch(_GnssOutage):
    effect_keys = ("glitched_fixes",)

    def on(self, t: float) -> None:
        end = self.spec.end_s(self.emu.scn.duration_s)
        self.rx.add_glitch(t, max(end - t, 1e-9), tuple(self.spec.offset_enu_m))

    def _counts(self) -> dict[str, int]:
        return {"glitched_fixes": self.rx.glitched_fixes}


class _GnssDegraded(_GnssOutage):
    effect_keys = ("degraded_fixes", "epochs_without_fix")

    def on(self, t: float) -> None:
        s = self.spec
        self.rx.set_degraded(s.noise_scale, s.num_sats, s.hdop, s.fix_quality)

    def off(self, t: float) -> None:
        self.rx.clear_degraded()

    def _counts(self) -> dict[str, int]:
        return {"degraded_fixes": self.rx.degraded_fixes, "epochs_without_fix": self.rx.no_fix_epochs}


# ================================================================================ PSNS
def _psns(emu: "Emulator", kind: str) -> tuple[Any, Any]:
    s = emu.sensors
    cam = getattr(s, "psns", None) if s is not None else None
    comp = getattr(s, "compass", None) if s is not None else None
    if cam is None and comp is None:
        raise _bind_error(kind, "needs a modelled polarization sensor (camera or compass) on a mem:// psns link")
    return cam, comp


class _PsnsCloudCover(Injector):
    effect_keys = ("rays_in_cloud",)

    def __init__(self, *a: Any) -> None:
        super().__init__(*a)
        _psns(self.emu, self.kind)
        self.sky = self.emu.sensors.sky
        self.cloud: Any = None

    @property
    def target(self) -> str:
        s = self.spec
        return f"sky around az {s.az_deg:g} deg, el {s.el_deg:g} deg"

    def on(self, t: float) -> None:
        from ..world.sky import textured_cloud

        s = self.spec
        self.cloud = textured_cloud(self.rng, s.az_deg * DEG, s.el_deg * DEG, s.radius_deg * DEG, s.dop_scale,
                                    s.aop_sigma_deg * DEG, s.intensity_scale, 0.0, math.inf, s.drift_az_dps * DEG)
        self.sky.clouds.append(self.cloud)

    def off(self, t: float) -> None:
        if self.cloud in self.sky.clouds:
            self.sky.clouds.remove(self.cloud)

    def _counts(self) -> dict[str, int]:
        return {"rays_in_cloud": self.cloud.hits if self.cloud is not None else 0}

    def start(self, t: float) -> None:
        self.on(t)  # the cloud (and its counter) exists from now on
        self._c0 = self._counts()
        self.active = True
        self.t_on = t


class _PsnsSunOccluded(_PsnsCloudCover):
    effect_keys = ("rays_near_sun_hidden",)

    @property
    def target(self) -> str:
        return f"sky within {self.spec.radius_deg:g} deg of the sun"

    def on(self, t: float) -> None:
        from ..world.sky import SunOccluder

        s = self.spec
        self.cloud = SunOccluder(s.radius_deg * DEG, s.dop_scale, s.intensity_scale)
        self.sky.sun_occluders.append(self.cloud)

    def off(self, t: float) -> None:
        if self.cloud in self.sky.sun_occluders:
            self.sky.sun_occluders.remove(self.cloud)

    def _counts(self) -> dict[str, int]:
        return {"rays_near_sun_hidden": self.cloud.hits if self.cloud is not None else 0}


class _PsnsUnitBlocked(Injector):
    def __init__(self, *a: Any) -> None:
        super().__init__(*a)
        self.cam, self.comp = _psns(self.emu, self.kind)
        self.effect_keys = ("unit_readings_blocked",) if self.comp is not None else ("frames_blocked",)
        if self.comp is not None and self.kind == "psns_unit_blocked":
            n = len(self.comp.model.mountings)
            units = self.spec.units
            self.units = list(range(n)) if units is None else list(units)
            bad = [u for u in self.units if u >= n]
            if bad:
                raise _bind_error(self.kind, f"blocks units {bad}, but the compass has units 0..{n - 1}")

    @property
    def target(self) -> str:
        if self.comp is not None:
            u = self.spec.units
            return "compass units " + ("all" if u is None else ", ".join(str(x) for x in u))
        return "polarization camera"

    def on(self, t: float) -> None:
        if self.comp is not None:  # the compass's own blocked-units schedule (issue 6): a window from now
            end = self.spec.end_s(self.emu.scn.duration_s)
            self.comp.model.block_units(self.units, t, max(end, t + 1e-9))
        else:
            self.cam.set_blocked(True)

    def off(self, t: float) -> None:
        if self.comp is None:
            self.cam.set_blocked(False)

    def _counts(self) -> dict[str, int]:
        if self.comp is not None:
            return {"unit_readings_blocked": self.comp.model.blocked_readings}
        return {"frames_blocked": self.cam.frames_blocked}


class _PsnsInstallationError(_PsnsUnitBlocked):
    def __init__(self, *a: Any) -> None:
        super().__init__(*a)
        self.effect_keys = ("frames_with_error",)

    @property
    def target(self) -> str:
        return "compass mounting" if self.comp is not None else "camera mounting"

    def on(self, t: float) -> None:
        rv = np.asarray(self.spec.rotation_deg, dtype=np.float64) * DEG
        (self.comp if self.comp is not None else self.cam).model.set_mounting_error(rv)

    def off(self, t: float) -> None:
        (self.comp if self.comp is not None else self.cam).model.set_mounting_error(None)

    def _counts(self) -> dict[str, int]:
        if self.comp is not None:
            return {"frames_with_error": self.comp.model.readings_with_mounting_error}
        return {"frames_with_error": self.cam.model.frames_with_mounting_error}


# ================================================================================ IMU
def _imu(emu: "Emulator", kind: str, sensor: str) -> Any:
    s = emu.sensors
    dev = getattr(s, sensor, None) if s is not None else None
    if dev is None:
        raise _bind_error(kind, f"needs the modelled {'STIM210 gyro on a mem:// gyro link' if sensor == 'gyro' else 'accelerometers'}")
    return dev


class _ImuBiasStep(Injector):
    effect_keys = ("samples_biased",)

    def __init__(self, *a: Any) -> None:
        super().__init__(*a)
        self.sensor = self.spec.sensor
        self.dev = _imu(self.emu, self.kind, self.sensor)

    @property
    def target(self) -> str:
        return self.sensor

    def on(self, t: float) -> None:
        s = self.spec
        if self.sensor == "gyro":
            delta = np.asarray(s.gyro_deg_h, dtype=np.float64) * (DEG / 3600.0)
        else:
            delta = np.asarray(s.accel_mg, dtype=np.float64) * (1e-3 * G_STD)
        self.dev.set_bias_step(("fault", self.index), delta)

    def off(self, t: float) -> None:
        self.dev.set_bias_step(("fault", self.index), None)

    def _counts(self) -> dict[str, int]:
        return {"samples_biased": self.dev.faults.biased}


class _ImuStuckAxis(_ImuBiasStep):
    effect_keys = ("samples_stuck",)

    @property
    def target(self) -> str:
        return f"{self.sensor} axes {', '.join(self.spec.axes)}"

    def on(self, t: float) -> None:
        for a in self.spec.axes:
            self.dev.set_stuck_axis(_AXES[a], True)

    def off(self, t: float) -> None:
        for a in self.spec.axes:
            self.dev.set_stuck_axis(_AXES[a], False)

    def _counts(self) -> dict[str, int]:
        return {"samples_stuck": self.dev.faults.stuck_samples}


class _ImuSaturation(_ImuBiasStep):
    effect_keys = ("samples_clipped",)

    def on(self, t: float) -> None:
        s = self.spec
        lim = s.gyro_range_dps * DEG if self.sensor == "gyro" else s.accel_range_g * G_STD
        self.dev.set_range_limit(lim)

    def off(self, t: float) -> None:
        self.dev.set_range_limit(None)

    def _counts(self) -> dict[str, int]:
        return {"samples_clipped": self.dev.faults.clipped}


class _ImuDroppedDatagrams(Injector):
    effect_keys = ("datagrams_dropped",)

    def __init__(self, *a: Any) -> None:
        super().__init__(*a)
        self.dev = _imu(self.emu, self.kind, "gyro")

    @property
    def target(self) -> str:
        return "gyro"

    def on(self, t: float) -> None:
        self.dev.set_datagram_drop(self.spec.probability, self.rng)

    def off(self, t: float) -> None:
        self.dev.set_datagram_drop(0.0)

    def _counts(self) -> dict[str, int]:
        return {"datagrams_dropped": self.dev.datagrams_dropped}


# ================================================================================ links
def _link(emu: "Emulator", kind: str, name: str) -> Link:
    link = emu.links.get(name)
    if link is None:
        raise _bind_error(kind, f"no link {name!r} (links: {', '.join(emu.links)})")
    return link


class _ByteFault(Injector):
    """Base of the faults that sit in a link's byte hooks (``Link.faults_in`` / ``faults_out``)."""

    directions: tuple[str, ...] = ()

    def __init__(self, *a: Any) -> None:
        super().__init__(*a)
        self.link = _link(self.emu, self.kind, self.spec.link)
        if not self.directions:
            self.directions = ("in",) if self.spec.effective_direction() == "to_dsp" else ("out",)
        self._acc = {k: 0 for k in self.effect_keys}

    @property
    def target(self) -> str:
        d = getattr(self.spec, "effective_direction", None)
        return f"link {self.spec.link}" + (f" {d()}" if d is not None else "")

    def on(self, t: float) -> None:
        for d in self.directions:
            (self.link.faults_in if d == "in" else self.link.faults_out).append(self)

    def off(self, t: float) -> None:
        for d in self.directions:
            hooks = self.link.faults_in if d == "in" else self.link.faults_out
            if self in hooks:
                hooks.remove(self)

    def count(self, key: str, n: int) -> None:
        self._acc[key] = self._acc.get(key, 0) + n
        st = self.link.stats
        st.faults[self.kind] = st.faults.get(self.kind, 0) + n
        if key == "bytes_corrupted":
            st.corrupted_bytes += n

    def apply(self, link: Link, direction: str, t: float, data: bytes) -> bytes:  # ByteFault
        raise NotImplementedError


class _LinkBitErrors(_ByteFault):
    """Bits flip at ``ber`` per bit on the wire. A flipped data bit corrupts the byte; a flipped start or
    stop bit is a framing error and a flipped parity bit a parity error (the receiver drops the byte)."""

    effect_keys = ("bytes_corrupted", "framing_errors", "parity_errors")

    def _ber(self) -> float:
        return float(self.spec.ber)

    def apply(self, link: Link, direction: str, t: float, data: bytes) -> bytes:
        return self._flip(link, data, self._ber())

    def _flip(self, link: Link, data: bytes, ber: float) -> bytes:
        line = link.line
        nd = line.data_bits
        has_par = line.parity != "N"
        bpb = int(1 + nd + (1 if has_par else 0) + math.ceil(line.stop_bits))
        n = len(data)
        k = int(self.rng.binomial(n * bpb, ber))
        if k == 0:
            return data
        pos = self.rng.integers(0, n * bpb, k)
        out = bytearray(data)
        lost = np.zeros(n, dtype=bool)
        flipped = np.zeros(n, dtype=bool)
        fe = pe = 0
        for p in pos.tolist():
            i, b = divmod(p, bpb)
            if b == 0 or b >= 1 + nd + (1 if has_par else 0):  # start or stop bit
                if not lost[i]:
                    fe += 1
                lost[i] = True
            elif has_par and b == 1 + nd:
                if not lost[i]:
                    pe += 1
                lost[i] = True
            else:
                out[i] ^= 1 << (b - 1)
                flipped[i] = True
        corrupted = int(np.count_nonzero(flipped & ~lost))
        if corrupted:
            self.count("bytes_corrupted", corrupted)
        if fe:
            self.count("framing_errors", fe)
            link.stats.framing_errors += fe
        if pe:
            self.count("parity_errors", pe)
            link.stats.parity_errors += pe
        if lost.any():
            return bytes(b for b, gone in zip(out, lost.tolist()) if not gone)
        return bytes(out)


class _LinkByteDrops(_ByteFault):
    effect_keys = ("bytes_dropped",)

    def apply(self, link: Link, direction: str, t: float, data: bytes) -> bytes:
        n = len(data)
        k = int(self.rng.binomial(n, float(self.spec.probability)))
        if k == 0:
            return data
        gone = set(self.rng.choice(n, size=k, replace=False).tolist())
        self.count("bytes_dropped", k)
        if direction == "in":
            link.stats.dropped_in += k
        else:
            link.stats.dropped_out += k
        return bytes(b for i, b in enumerate(data) if i not in gone)


class _LinkNoiseBurst(_LinkBitErrors):
    effect_keys = ("bytes_corrupted", "framing_errors", "parity_errors", "spurious_bytes")

    def apply(self, link: Link, direction: str, t: float, data: bytes) -> bytes:
        out = self._flip(link, data, float(self.spec.ber))
        lam = float(self.spec.spurious_per_byte) * len(data)
        m = int(self.rng.poisson(lam)) if lam > 0 else 0
        if m == 0:
            return out
        buf = bytearray(out)
        junk = self.rng.integers(0, 256, m).tolist()
        where = np.sort(self.rng.integers(0, len(buf) + 1, m))[::-1].tolist()
        for w, b in zip(where, junk):
            buf.insert(w, b)
        self.count("spurious_bytes", m)
        return bytes(buf)


class _LinkDisconnect(_ByteFault):
    effect_keys = ("bytes_lost",)
    directions = ("in", "out")

    @property
    def target(self) -> str:
        return f"link {self.spec.link} (both directions)"

    def apply(self, link: Link, direction: str, t: float, data: bytes) -> bytes:
        n = len(data)
        self.count("bytes_lost", n)
        if direction == "in":
            link.stats.dropped_in += n
        else:
            link.stats.dropped_out += n
        return b""


class _LinkStall(_ByteFault):
    """Bytes wait while the line is stalled, up to the transmitter's queue; the rest is lost. They go on
    when the stall ends (delivered at that instant: the line's pacing of the backlog is not modelled)."""

    effect_keys = ("bytes_held", "bytes_dropped")

    def __init__(self, *a: Any) -> None:
        super().__init__(*a)
        peer = getattr(self.link, "peer", None)
        if self.directions == ("in",) and peer is not None:
            self.capacity = peer.line.tx_queue_bytes
        else:
            self.capacity = self.link.line.tx_queue_bytes
        self.held = bytearray()

    def apply(self, link: Link, direction: str, t: float, data: bytes) -> bytes:
        room = self.capacity - len(self.held)
        keep = data[:max(room, 0)]
        lost = len(data) - len(keep)
        if keep:
            self.held += keep
            self.count("bytes_held", len(keep))
        if lost:
            self.count("bytes_dropped", lost)
            if direction == "in":
                link.stats.dropped_in += lost
            else:
                link.stats.dropped_out += lost
        return b""

    def off(self, t: float) -> None:
        super().off(t)
        held, self.held = bytes(self.held), bytearray()
        if held:
            self.link.deliver_held(self.directions[0], held)


class _LinkBaudMismatch(Injector):
    effect_keys = ("framing_errors", "parity_errors")

    def __init__(self, *a: Any) -> None:
        super().__init__(*a)
        self.link = _link(self.emu, self.kind, self.spec.link)
        peer = getattr(self.link, "peer", None)
        self.tx: LineConfig = peer.line if peer is not None else self.link.line
        s = self.spec
        base = self.link.line.baud
        baud = s.rx_baud if s.rx_baud is not None else int(round(base * (1.0 + s.baud_error_pct / 100.0)))
        self.rx = self.link.line.with_(baud=max(1, baud))

    @property
    def target(self) -> str:
        return f"link {self.spec.link} receiver at {self.rx.baud} baud (transmitter {self.tx.baud})"

    def on(self, t: float) -> None:
        self.link.set_remote_line(self.tx, self.rx)

    def off(self, t: float) -> None:
        self.link.set_remote_line(self.tx)

    def _counts(self) -> dict[str, int]:
        st = self.link.stats
        return {"framing_errors": st.framing_errors, "parity_errors": st.parity_errors}


# ================================================================================ FPGA, DSP
class _FpgaChannelStall(Injector):
    effect_keys = ("held_back",)

    @property
    def target(self) -> str:
        return f"FPGA channel {self.spec.channel}"

    def on(self, t: float) -> None:
        self.emu.fpga.set_channel_stalled(self.spec.channel, True)  # type: ignore[union-attr]

    def off(self, t: float) -> None:
        self.emu.fpga.set_channel_stalled(self.spec.channel, False)  # type: ignore[union-attr]

    def _counts(self) -> dict[str, int]:
        return {"held_back": self.emu.fpga.stall_counts.get(self.spec.channel, 0)}  # type: ignore[union-attr]


class _DspExtraLoad(Injector):
    effect_keys = ("ticks_loaded",)

    def __init__(self, *a: Any) -> None:
        super().__init__(*a)
        s = self.spec
        dsp = self.emu.dsp
        if dsp is None or not hasattr(dsp, "extra_cycles_per_tick"):
            raise _bind_error(self.kind, "needs the virtual DSP in this process (not a split run's remote DSP)")
        budget = dsp.clock_hz / self.emu.scn.sensors.imu.rate_hz
        self.cycles = int(s.cycles_per_tick) if s.cycles_per_tick is not None else int(round(s.load_pct / 100.0 * budget))

    @property
    def target(self) -> str:
        return f"DSP (+{self.cycles} cycles per tick)"

    def on(self, t: float) -> None:
        self.emu.dsp.extra_cycles_per_tick += self.cycles  # type: ignore[union-attr]

    def off(self, t: float) -> None:
        self.emu.dsp.extra_cycles_per_tick -= self.cycles  # type: ignore[union-attr]

    def _counts(self) -> dict[str, int]:
        dsp = self.emu.dsp
        return {"ticks_loaded": dsp.extra_load_ticks, "deadline_misses": dsp.deadline_misses}  # type: ignore[union-attr]


INJECTORS: dict[str, type[Injector]] = {
    "gnss_outage": _GnssOutage, "gnss_glitch": _GnssGlitch, "gnss_degraded": _GnssDegraded,
    "psns_cloud_cover": _PsnsCloudCover, "psns_unit_blocked": _PsnsUnitBlocked,
    "psns_sun_occluded": _PsnsSunOccluded, "psns_installation_error": _PsnsInstallationError,
    "imu_bias_step": _ImuBiasStep, "imu_stuck_axis": _ImuStuckAxis, "imu_saturation": _ImuSaturation,
    "imu_dropped_datagrams": _ImuDroppedDatagrams,
    "link_bit_errors": _LinkBitErrors, "link_byte_drops": _LinkByteDrops, "link_noise_burst": _LinkNoiseBurst,
    "link_baud_mismatch": _LinkBaudMismatch, "link_disconnect": _LinkDisconnect, "link_stall": _LinkStall,
    "fpga_channel_stall": _FpgaChannelStall, "dsp_extra_load": _DspExtraLoad,
}


def _bind_error(kind: str, msg: str) -> ScenarioError:
    return ScenarioError(ScenarioIssue("<scenario>", None, None, f"faults.{kind}", f"{kind} {msg}"))


class FaultScheduler:
    """The scenario's faults on the emulator's clock (see module docstring).

    Parameters
    ----------
    emu : the assembled emulator (devices, links, FPGA, DSP).
    faults : the scenario's ``faults`` section.
    seed : the run's seed.
    events : where ``fault_start`` / ``fault_end`` go (the recorder).
    """

    def __init__(self, emu: "Emulator", faults: list[Fault], seed: int, events: EventSink) -> None:
        self.emu = emu
        self.events = events
        self.injectors: list[Injector] = []
        self._fw0: dict[int, dict[str, int]] = {}
        self._fw_delta: dict[int, dict[str, int]] = {}
        for i, f in enumerate(faults):
            kind = f.kind
            cls = INJECTORS[kind]
            try:
                inj = cls(emu, kind, f.spec, i, device_rng(seed, f"fault:{i}:{kind}"))
            except ScenarioError as exc:
                for issue in exc.issues:
                    issue.file = emu.scn.source_file
                    issue.path = f"faults[{i}].{kind}"
                raise ScenarioError(exc.issues) from None
            self.injectors.append(inj)

    def start(self) -> None:
        """Schedule every fault (call right after the scenario clock restarted at 0)."""
        loop = self.emu.loop
        assert loop is not None
        dur = self.emu.scn.duration_s
        for inj in self.injectors:
            spec = inj.spec
            loop.call_at(spec.start_s, self._on, inj)
            end = spec.end_s(dur)
            if end < dur:
                loop.call_at(end, self._off, inj)

    def _fw_counters(self) -> dict[str, int]:
        fw = self.emu.fw
        c = getattr(fw, "counters", {}) if fw is not None else {}
        return {k: int(c.get(k, 0)) for k in FIRMWARE_COUNTERS}

    def _on(self, inj: Injector) -> None:
        t = self.emu.loop.time()  # type: ignore[union-attr]
        self._fw0[inj.index] = self._fw_counters()
        inj.start(t)
        spec = inj.spec
        self.events.emit(t, "fault", "fault_start", fault=inj.kind, index=inj.index, target=inj.target,
                         end_s=spec.end_s(self.emu.scn.duration_s))

    def _off(self, inj: Injector) -> None:
        if not inj.active:
            return
        t = self.emu.loop.time()  # type: ignore[union-attr]
        inj.stop(t)
        fw1 = self._fw_counters()
        fw0 = self._fw0.get(inj.index, {})
        self._fw_delta[inj.index] = {k: fw1[k] - fw0.get(k, 0) for k in fw1 if fw1[k] != fw0.get(k, 0)}
        self.events.emit(t, "fault", "fault_end", fault=inj.kind, index=inj.index, target=inj.target,
                         evidence=inj.evidence(), fired=inj.fired, firmware=self._fw_delta[inj.index])

    def finish(self) -> list[dict[str, Any]]:
        """End the faults still active (at the current time) and return one record per fault."""
        for inj in self.injectors:
            if inj.active:
                self._off(inj)
        return [self.record(inj) for inj in self.injectors]

    def record(self, inj: Injector) -> dict[str, Any]:
        return {"index": inj.index, "kind": inj.kind, "target": inj.target, "start_s": inj.spec.start_s,
                "end_s": inj.spec.end_s(self.emu.scn.duration_s), "active_from_s": inj.t_on,
                "active_until_s": inj.t_off, "evidence": inj.evidence(), "effect": list(inj.effect_keys),
                "fired": inj.fired if inj.t_on is not None else None,
                "firmware": self._fw_delta.get(inj.index, {})}

    @property
    def valid(self) -> bool:
        """False when a fault that was switched on never took effect."""
        return all(inj.fired for inj in self.injectors if inj.t_on is not None)
