"""The variants in the firmware's loop: the firmware interface (docs/architecture.md "Firmware interface") unchanged
for the base variant, the VARIANT block and STATUS
mode for the others, a switch by host command, and the 200 Hz cycle budget (worst tick per variant)."""

from __future__ import annotations

import pytest

from firmware_model import Firmware, FirmwareConfig
from firmware_model.psns_geometry import CameraGeometry, compass_unit_mountings
from firmware_model.variants.common import compass_mountings
from protocols.host import FilterVariant, HostFormat, HostStatus, NavSolution, SelectVariant, encode_command
from protocols.stream import StreamDecoder

from .streams import (
    CameraSpec,
    CompassSpec,
    GnssSpec,
    ImuErrors,
    MagSpec,
    StreamSpec,
    run,
    static_trajectory,
    stream,
)

IMU = ImuErrors((9.0, -7.0, 3.0), 0.15, (1500.0, -1000.0, 2000.0), 100.0)
THREE = compass_mountings([(0.0, 0.0), (45.0, 0.0), (45.0, 90.0)])
FISHEYE = CameraGeometry(projection="fisheye", focal_m=1.8e-3)


def _setup(variant: str, duration_s: float) -> tuple[FirmwareConfig, StreamSpec]:
    traj = static_trajectory(30.0, 2.0, -3.0)
    gnss = GnssSpec(True, 3.0, 0.03)
    if variant == "dual_vector":
        return (FirmwareConfig(filter=variant, compass_mountings=THREE, initial_heading_deg=30.5),
                StreamSpec(traj, duration_s, imu=IMU, gnss=gnss, psns="compass", compass=CompassSpec(THREE)))
    if variant == "sun_elevation":
        return (FirmwareConfig(filter=variant, initial_heading_deg=30.5),
                StreamSpec(traj, duration_s, imu=IMU, gnss=gnss, psns="compass", psns_rate_hz=5,
                           compass=CompassSpec(compass_unit_mountings())))
    if variant == "kmeans_3d":
        return (FirmwareConfig(filter=variant, camera=FISHEYE, initial_heading_deg=30.5),
                StreamSpec(traj, duration_s, imu=IMU, gnss=gnss, psns="camera", psns_rate_hz=2,
                           camera=CameraSpec(FISHEYE, stride_px=64, aop_sigma_deg=0.1), mag=MagSpec()))
    return (FirmwareConfig(filter=variant, initial_heading_deg=30.5),
            StreamSpec(traj, duration_s, imu=IMU, gnss=gnss, psns="solar_vector", sun_sigma=0.001))


def _frames(fw: Firmware, spec: StreamSpec) -> tuple[list[NavSolution], list[HostStatus], list[dict]]:
    dec = StreamDecoder([HostFormat()])
    navs, stats, events = [], [], []
    for t_rx, uart, data in stream(spec):
        fw.receive(uart, data, t_rx)
        if uart == 1:
            for r in fw.service():
                events.extend(r.events)
                for _, out, _ in r.outputs:
                    for f in dec.feed(out):
                        (navs if isinstance(f, NavSolution) else stats if isinstance(f, HostStatus) else []).append(f)
    return navs, stats, events


def test_base_variant_frames_and_events_are_unchanged_by_the_seam():
    cfg, spec = _setup("base", 10.0)
    navs, stats, events = _frames(Firmware(cfg), spec)
    assert navs and all(n.variant_mode is None for n in navs)  # 102-byte NAV_SOLUTION as before
    assert stats and all(s.variant_mode == 0 and s.filter_variant == int(FilterVariant.BASE) for s in stats)
    assert {e["event"] for e in events} <= {"alignment_done", "gnss_update", "psns_rejected", "fine_alignment_done"}


@pytest.mark.parametrize("variant", ["dual_vector", "kmeans_3d", "federated", "sun_elevation"])
def test_variants_fill_the_variant_block_and_status(variant):
    cfg, spec = _setup(variant, 8.0)
    fw = Firmware(cfg)
    navs, stats, events = _frames(fw, spec)
    tail = [n for n in navs if n.time_s > 5.0]
    assert tail and all(n.variant_mode is not None for n in tail)
    assert (tail[-1].mode >> 8) & 0xF == int(fw.filter.variant_id)
    assert stats[-1].variant_mode == tail[-1].variant_mode and stats[-1].filter_variant == fw.filter.variant_id
    assert any(e.get("variant") == variant for e in events)  # the mode manager's decisions reach TickResult.events
    # each variant used its own measurements (admitted counters merged into the firmware's)
    assert any(k.endswith("_admitted") and v > 0 for k, v in fw.counters.items())


def test_select_variant_command_switches_to_a_registered_variant_that_keeps_navigating():
    cfg, spec = _setup("dual_vector", 12.0)
    cfg.filter = "base"
    fw = Firmware(cfg)
    cmd = encode_command(SelectVariant(token=3, variant=int(FilterVariant.DUAL_VECTOR)))
    sent = False
    dec = StreamDecoder([HostFormat()])
    navs = []
    for t_rx, uart, data in stream(spec):
        fw.receive(uart, data, t_rx)
        if uart == 1:
            if not sent and t_rx > 6.0:
                fw.receive(0, cmd, t_rx)
                sent = True
            for r in fw.service():
                for _, out, _ in r.outputs:
                    navs.extend(f for f in dec.feed(out) if isinstance(f, NavSolution))
    assert fw.filter.name == "dual_vector" and fw.filter.host is fw.core
    assert navs[-1].variant_mode == 2 and navs[-1].psns_q_mask == 0b111  # sun-error-vector mode, all reliable
    assert fw.counters.get("sun_vector_admitted", 0) > 20


@pytest.mark.parametrize("variant", ["base", "dual_vector", "kmeans_3d", "federated", "sun_elevation"])
def test_worst_tick_per_variant_stays_inside_the_200_hz_budget(variant, capsys):
    cfg, spec = _setup(variant, 20.0)
    fw = Firmware(cfg)
    run(fw, spec, sample_every_s=5.0)
    tick = fw.meter.tasks["imu_tick"]
    pct = 100.0 * tick.cycles_max / fw.meter.tick_budget
    with capsys.disabled():
        print(f"\n{variant}: worst tick {tick.cycles_max} cycles ({pct:.2f} % of {fw.meter.tick_budget}), "
              f"average {tick.cycles_avg:.0f}")
    assert pct < 20.0


def _ticks(fw: Firmware, events: list[tuple[float, int, bytes]]) -> list[tuple[object, ...]]:
    out = []
    for t_rx, uart, data in events:
        fw.receive(uart, data, t_rx)
        if uart == 1:
            out.extend((r.t_fpga_s, r.cycles, r.outputs, r.events, [vars(s) for s in r.solar_solves])
                       for r in fw.service())
    return out


@pytest.mark.parametrize("variant", ["base", "kmeans_3d"])
def test_packed_points_give_the_ticks_of_point_objects(variant):
    """The loop's PSNS decoder hands POLARIZATION_OBS points over as their bytes (``PsnsFormat(packed_points=True)``,
    no object per point: performance.md 5.7, D-10.E9); with the plain decoder (point objects) every tick is the
    same: time, cycles, output bytes, events, solar solves (the firmware's solve and the K-means variant's raw
    frames)."""
    from protocols.psns import PsnsFormat

    from ..synth import SensorErrors, StaticTruth, StreamConfig, static_stream

    if variant == "base":
        cfg = FirmwareConfig(initial_heading_deg=30.5)
        err = SensorErrors(gyro_bias_dph=(5, -3, 4), gyro_arw_deg_rt_h=0.15, accel_bias_mg=(1, -1, 0.5),
                           accel_noise_ug_rt_hz=100, gnss_pos_sigma_m=3, gnss_vel_sigma_mps=0.03,
                           psns_sigma_deg=0.03)
        events = list(static_stream(StaticTruth(), err, StreamConfig(psns="polarization_obs"), 12.0))
    else:
        cfg, spec = _setup(variant, 12.0)
        events = list(stream(spec))
    rows_fw, objs_fw = Firmware(cfg), Firmware(cfg)
    objs_fw._dec_psns = StreamDecoder([PsnsFormat()])  # the plain path: a PolarizationPoint per point
    rows, objs = _ticks(rows_fw, events), _ticks(objs_fw, events)
    assert rows == objs
    assert rows_fw.counters == objs_fw.counters and rows_fw.counters["psns_frames"] >= 20
    solved = sum(len(t[4]) for t in rows) if variant == "base" else rows_fw.counters.get("psns_updates", 0)
    assert solved > 0
