"""The mode manager logs each change of decision with its reason and counts every decision."""

from __future__ import annotations

from firmware_model.variants.mode_manager import ModeManager
from firmware_model.variants.params import ModeManagerParams


def test_a_run_of_identical_decisions_is_one_event_with_its_repeat_count():
    mm = ModeManager("test")
    for t in range(5):
        mm.decide(float(t), "unit0", True, "ok")
    mm.decide(5.0, "unit0", False, "low_dop", dop=0.01)
    mm.decide(6.0, "unit0", False, "low_dop", dop=0.02)
    mm.decide(7.0, "unit0", False, "chi2_fail")  # same verdict, new reason: logged
    mm.decide(8.0, "unit0", True, "ok")
    ev = mm.drain()
    assert [(e["event"], e["reason"], e["repeats"]) for e in ev] == [
        ("measurement_admitted", "ok", 0), ("measurement_rejected", "low_dop", 5),
        ("measurement_rejected", "chi2_fail", 2), ("measurement_admitted", "ok", 1)]
    assert ev[1]["dop"] == 0.01 and ev[1]["channel"] == "unit0" and ev[1]["variant"] == "test"
    assert mm.counters == {"unit0_admitted": 6, "unit0_rejected": 3}
    assert mm.drain() == []


def test_chi_square_gate_uses_the_configured_alpha():
    mm = ModeManager("test", ModeManagerParams(chi2_alpha=0.05))
    assert mm.gate(0.0, "gnss", 12.5, 6)  # chi2_0.95(6) = 12.592
    assert not mm.gate(1.0, "gnss", 12.7, 6)
    e = mm.drain()[-1]
    assert e["reason"] == "chi2_fail" and e["threshold"] == 12.592 and e["dof"] == 6 and e["nis"] == 12.7


def test_modes_are_logged_on_change_with_the_previous_value():
    mm = ModeManager("test")
    assert mm.set_mode(0.0, "psns_mode", "sun", "two")
    assert not mm.set_mode(1.0, "psns_mode", "sun", "two")
    assert mm.set_mode(2.0, "psns_mode", "none", "zero")
    ev = mm.drain()
    assert [(e["mode"], e.get("previous")) for e in ev] == [("sun", None), ("none", "sun")]
    mm.event(3.0, "gnss_isolated", "chi2_fail", nis=30.0)
    mm.event(4.0, "gnss_isolated", "chi2_fail", nis=31.0)  # decisions by themselves: always logged
    assert len(mm.drain()) == 2 and mm.counters["gnss_isolated"] == 2
