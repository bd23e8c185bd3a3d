"""The hostile-input corpus (docs/hostile-input.md) fed to every filter variant: no exception, no NaN, and the
navigation back within its normal accuracy after each case within the case's bound."""

from __future__ import annotations

import pytest

from firmware_model import Firmware, FirmwareConfig
from firmware_model.config import FILTER_VARIANTS

from .hostile import CASES, STATE_UPSETS, T_BAD, run_case, sentence

#: heading (deg), level (deg) and horizontal position (m) errors of "normal accuracy" on this static stream
NORMAL = (1.0, 0.2, 15.0)
#: recovery bound (s after the hostile window ends) per case; the measured times are in docs/hostile-input.md
BOUND_S = {name: 0.0 for name in CASES} | {"state_heading_flip_150deg": 40.0, "state_covariance_nan": 5.0}
VARIANTS = sorted(FILTER_VARIANTS)


@pytest.mark.parametrize("variant", VARIANTS)
@pytest.mark.parametrize("case", sorted(CASES) + sorted(STATE_UPSETS))
def test_corpus_case_recovers(case: str, variant: str) -> None:
    r = run_case(case, variant)  # strict: an exception from the input fails the test
    assert not r.any_nan
    assert r.samples and r.samples[-1][0] >= T_BAD[1] + BOUND_S[case] + 5.0
    rec = r.recovery_s(*NORMAL)
    assert rec <= BOUND_S[case], (case, variant, rec, r.worst_after(T_BAD[1]))
    if case in CASES and case not in ("gga_jump_5km", "pvt_leap_second"):  # refused at the boundary, counted
        assert r.counters["input_rejected"] > 0, r.counters
    assert r.counters["input_faults"] == 0


def test_gate_refuses_an_in_range_jump() -> None:
    r = run_case("gga_jump_5km", "base")
    assert r.counters.get("gnss_rows_gated", 0) >= 2
    # the gate's state is in the nav frame: bit 7 of gnss_status while the jumped fixes are refused, clear after
    gated = [t for t, st in r.gnss_status if st & 0x80]
    assert gated and T_BAD[0] <= min(gated) and max(gated) <= T_BAD[1] + 1.5, (min(gated), max(gated), T_BAD)
    assert all(st & 0x7F == 1 for _t, st in r.gnss_status if st)  # the quality bits keep the GGA code
    assert not any(st & 0x80 for t, st in r.gnss_status if t > T_BAD[1] + 1.5)


def test_heading_flip_is_detected_and_reported() -> None:
    r = run_case("state_heading_flip_150deg", "base")
    rec = [e for e in r.events if e["event"] == "filter_recovery"]
    assert rec and rec[0]["reason"] == "psns_rejected" and rec[0]["action"] == "re-alignment"
    assert r.counters["fdir_recoveries"] == 1


def test_issue_minimal_rmc_course_inf_does_not_raise() -> None:
    fw = Firmware()
    fw.raise_faults = True
    fw.receive(3, b"$GPRMC,020020.00,A,3958.74626,N,11620.34682,E,9.723,inf,180919,,,A*1F\r\n")
    assert fw.counters["input_rejected_not_finite"] == 1


def test_leap_second_sets_utc_and_month_13_is_counted() -> None:
    r = run_case("pvt_leap_second", "base")
    assert r.counters.get("input_rejected_date", 0) == 0
    r = run_case("pvt_month_13", "base")
    assert r.counters["input_rejected_date"] >= 1


class _Boom(Exception):
    pass


def _boom(_s: object) -> None:
    raise _Boom


_RMC = sentence("GPRMC,020020.00,A,3958.74626,N,11620.34682,E,9.723,10.0,180919,,,A")


def test_exception_on_one_message_is_contained_counted_reported(monkeypatch: pytest.MonkeyPatch) -> None:
    fw = Firmware(FirmwareConfig())
    fw.raise_faults = False
    monkeypatch.setattr(fw.gnss, "_on_nmea", _boom)
    fw.receive(3, _RMC + _RMC)  # both messages reach the handler: one fault each, the second still handled
    assert fw.counters["input_faults"] == 2
    assert fw._fault_events[0]["event"] == "firmware_fault" and fw._fault_events[0]["error"] == "_Boom"


def test_strict_mode_fails_loudly(monkeypatch: pytest.MonkeyPatch) -> None:
    fw = Firmware(FirmwareConfig())
    fw.raise_faults = True
    monkeypatch.setattr(fw.gnss, "_on_nmea", _boom)
    with pytest.raises(_Boom):
        fw.receive(3, _RMC)


def test_imu_words_refused_exactly_at_the_24_bit_rails():
    """``check_imu_words``: a word at either rail (2^23 - 1, -2^23) is saturated, one inside is not, on every axis;
    the gyro's reason first (the chained comparisons of performance.md 5.7 keep the loop's rule)."""
    from firmware_model.input_guard import S24_MAX, S24_MIN, check_imu_words

    ok = (0, 0, 0)
    for axis in range(3):
        for w, bad in ((S24_MAX, True), (S24_MIN, True), (S24_MAX - 1, False), (S24_MIN + 1, False)):
            v = tuple(w if i == axis else 0 for i in range(3))
            assert check_imu_words(v, ok) == ("gyro_saturated" if bad else None)
            assert check_imu_words(ok, v) == ("accel_saturated" if bad else None)
            assert check_imu_words(v, v) == ("gyro_saturated" if bad else None)


def test_the_solar_criterion_re_aligns_only_a_box_at_rest() -> None:
    """D-5.43: the coarse alignment levels on the specific force, which is not gravity in a turn; so a run of refused
    solar vectors re-aligns a box at rest only (by its own horizontal speed), and at any speed when the limit is 0.
    The heading flip above (at rest) still re-aligns."""
    import numpy as np

    from firmware_model.nav_state import NavState

    fw = Firmware()
    fw.nav = NavState(q=np.array([1.0, 0.0, 0.0, 0.0]), v=np.array([0.3, 0.3, 2.0]), pos=np.zeros(3))
    assert fw._at_rest_for_realign()  # 0.42 m/s horizontal (the vertical does not count)
    fw.nav.v = np.array([0.4, 0.4, 0.0])
    assert not fw._at_rest_for_realign()  # 0.57 m/s: moving
    fw.cfg = FirmwareConfig(fdir_psns_realign_max_speed_mps=0.0)
    assert fw._at_rest_for_realign()
