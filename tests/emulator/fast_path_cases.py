"""The emulator's fast paths and their references, with inputs: ``CASES`` (see ``tests/test_fast_paths.py``).

Each case is ``pytest.param(reference, fast, inputs, id=...)``: ``<name>_fast`` beside ``<name>`` in the same
module, ``inputs`` a list of argument tuples; both must give equal results for every tuple.

Recording: the counting decoders (:func:`emulator.recording.counting.frame_counts` against
:func:`~emulator.recording.counting.frame_counts_fast`) on the golden vectors of the formats counted without
parsing, whole, chunked at random and damaged (bit errors, dropped and inserted bytes); the CSV rows
(:func:`emulator.recording.formatting.csv_row` against :func:`~emulator.recording.formatting.csv_row_fast`) on
rows of every kind of value the run directory's files get; the nav.csv and truth.csv rows
(:func:`emulator.recording.nav_error.nav_vs_truth_rows` against
:func:`~emulator.recording.nav_error.nav_vs_truth_rows_fast`, which keeps the previous frame's sigma cells) on
frames whose sigmas repeat, change, hold zeros of either sign, ints, numpy floats and non-finite values, in every
mode.
"""

from __future__ import annotations

import itertools
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from emulator.recording.counting import frame_counts, frame_counts_fast
from emulator.recording.formatting import csv_row, csv_row_fast
from emulator.recording.nav_error import nav_vs_truth_rows, nav_vs_truth_rows_fast
from emulator.world.trajectory import StaticTrajectory
from protocols.host import NavMode, NavSolution
from protocols.imu_frame import FpgaFrameFormat, ImuFrameFormat
from protocols.psns import PsnsFormat
from protocols.stim import Stim210Format

VECTORS = Path(__file__).resolve().parents[1] / "vectors"


def _hex(name: str) -> bytes:
    """The bytes of ``tests/vectors/<name>.hex`` (``#`` starts a comment, whitespace is ignored)."""
    text = (VECTORS / f"{name}.hex").read_text()
    return bytes.fromhex("".join("".join(line.split("#", 1)[0].split()) for line in text.splitlines()))


def _damaged(data: bytes, rng: np.random.Generator, rate: float) -> bytes:
    """``data`` with bit errors, dropped and inserted bytes at about ``rate`` per byte."""
    out = bytearray()
    for x in data:
        u = rng.random()
        if u < rate / 3:
            continue  # dropped
        if u < 2 * rate / 3:
            x ^= 1 << int(rng.integers(0, 8))  # bit error
        out.append(x)
        if u > 1 - rate / 3:
            out.append(int(rng.integers(0, 256)))  # inserted
    return bytes(out)


def _chunks(data: bytes, rng: np.random.Generator) -> list[bytes]:
    cut = [0]
    while cut[-1] < len(data):
        cut.append(cut[-1] + int(rng.integers(1, 97)))
    return [data[a:b] for a, b in itertools.pairwise(cut)]


def _counting_inputs() -> list[tuple[Any, ...]]:
    streams: list[tuple[list[Any], bytes]] = [
        ([Stim210Format("m")], _hex("stim210_m_hand") * 12 + _hex("damaged/stim210_truncated")),
        ([ImuFrameFormat()], _hex("imu_frame") * 9 + _hex("damaged/imu_bad_crc") + _hex("damaged/imu_bad_length")
         + _hex("damaged/imu_noise_between_frames") + _hex("damaged/imu_truncated") + _hex("imu_frame")),
        ([FpgaFrameFormat()], _hex("fpga_imu_and_mag") * 8 + _hex("damaged/imu_bad_crc")),
        ([PsnsFormat()], (_hex("psns_polarization_obs") + _hex("psns_compass") + _hex("psns_solar_vector")) * 4
         + _hex("damaged/psns_bad_crc") + _hex("damaged/psns_bad_length") + _hex("psns_solar_vector")),
    ]
    rng = np.random.default_rng(20261201)
    inputs: list[tuple[Any, ...]] = []
    for formats, data in streams:
        inputs.append((formats, [data]))
        inputs.append((formats, _chunks(data, rng)))
        inputs.append((formats, [bytes([b]) for b in data]))
        for rate in (0.001, 0.01, 0.05):
            inputs.append((formats, _chunks(_damaged(data * 4, rng, rate), rng)))
    return inputs


def _csv_inputs() -> list[tuple[Any, ...]]:
    rng = np.random.default_rng(7)
    finite = [float(x) for x in rng.normal(0.0, 1e3, 12)] + [0.0, -0.0, 1e-300, 5e-324, 1.7976931348623157e308,
                                                              39.979123456789, 1e16, 0.1 + 0.2]
    rows: list[tuple[Any, ...]] = [
        (finite,),
        ([1, 0, -7, 2**63, True, False, 3.5],),
        ([math.nan, 1.0, math.inf, -math.inf, 2],),
        ([np.float64(0.25), np.float32(0.1), np.int64(3), np.uint8(255), 1.5],),
        (["", "abc", "a b", "x,y", None, 1.0],),
        ([int(NavMode.NAVIGATING | NavMode.GNSS_AIDED), NavMode.NAVIGATING, 0.5],),
        ((12.0, 39.9, 116.3, 50.5, -0.01, 0.02, 0.0, 0.1, -0.2, 30.25),),
        ([],),
    ]
    return rows


def _nav_frame(k: int, sigma: tuple[Any, ...], mode: int, **fields: Any) -> tuple[float, NavSolution]:
    """(arrival time, frame) ``k`` of a frame sequence at 100 Hz, full-precision values near the truth's."""
    rng = np.random.default_rng(k)
    lat, lon, h, ve, vn, vu, roll, pitch, hdg = (float(x) for x in rng.normal(0.0, 1.0, 9))
    values: dict[str, Any] = dict(
        seq=k, time_s=0.01 * k, lat_deg=39.98 + 1e-5 * lat, lon_deg=116.34 + 1e-5 * lon, height_m=50.0 + h,
        vel_enu_mps=(ve, vn, vu), roll_deg=roll, pitch_deg=pitch, heading_deg=hdg % 360.0, sigma=sigma, mode=mode,
        gnss_status=1, psns_status=0, cpu_load_pct=2.94, deadline_misses=0)
    values.update(fields)
    return 0.01 * k + 0.0012, NavSolution(**values)


def _nav_inputs() -> list[tuple[Any, ...]]:
    nav, fine, coarse = int(NavMode.NAVIGATING), int(NavMode.NAVIGATING | NavMode.ALIGNING), int(NavMode.ALIGNING)
    s1 = tuple(float(x) for x in np.random.default_rng(1).random(9).astype(np.float32))
    s2 = (*s1[:8], s1[8] * 2.0)
    zeros, neg_zeros = (0.0,) * 9, (-0.0,) * 9
    ints, int_floats = (1, 2, 3, 4, 5, 6, 7, 8, 9), (1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0)
    sigmas_then: list[tuple[Any, ...]] = [
        s1, s1, s1, s2, s2, s1, zeros, neg_zeros, zeros, (*s1[:4], -0.0, *s1[5:]), s1,  # repeats, changes, zeros
        int_floats, ints, int_floats, ints, ints,  # ints equal to the floats of the previous frame
        s1, tuple(np.float64(x) for x in s1), s1, tuple(np.float32(x) for x in s1), s1,  # numpy floats
        (*s1[:8], math.nan), (*s1[:8], math.nan), s1, (*s1[:8], math.inf), (*s1[:8], math.inf), s1, s1,
        tuple(s1[:8]), tuple(s1[:8]), s1,  # another length
    ]
    steady = [_nav_frame(k, s, (coarse, fine, nav)[k % 3]) for k, s in enumerate(sigmas_then)]
    # hostile or unusual values outside the sigmas: the whole row by the reference, the next frames by the memo
    odd = [
        _nav_frame(100, s1, nav, lat_deg=math.nan), _nav_frame(101, s1, nav, height_m=math.inf),
        _nav_frame(102, s1, nav, roll_deg=np.float64(0.25)), _nav_frame(103, s1, coarse, cpu_load_pct=math.nan),
        _nav_frame(104, s1, nav, vel_enu_mps=(0.0, -0.0, 1e-300)), _nav_frame(105, s1, nav),
        _nav_frame(106, s1, fine, heading_deg=-0.0), _nav_frame(107, s1, 0), _nav_frame(108, s1, nav),
    ]
    long = [_nav_frame(200 + k, s1 if k % 5 else s2, nav if k > 20 else fine) for k in range(60)]
    traj = StaticTrajectory(39.98, 116.34, 50.0)
    return [(traj, steady), (traj, odd), (traj, long), (traj, steady + odd + long), (traj, [])]


CASES = [
    pytest.param(frame_counts, frame_counts_fast, _counting_inputs(), id="recording-counting-decoders"),
    pytest.param(csv_row, csv_row_fast, _csv_inputs(), id="recording-csv-row"),
    pytest.param(nav_vs_truth_rows, nav_vs_truth_rows_fast, _nav_inputs(), id="recording-nav-vs-truth-rows"),
]
