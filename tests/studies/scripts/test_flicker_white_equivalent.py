"""studies.scripts.flicker_white_equivalent: the one-channel check D-5.25 quotes."""

from __future__ import annotations

import math

from studies.scripts.flicker_white_equivalent import FLOOR, channel_nees


def test_white_equivalent_at_the_matching_time_underbounds_and_twice_it_does_not():
    """At the matching time of the vertical row (r = 0.1 m/s) the flicker's white equivalent leaves the filter
    overconfident (NEES about 1.5 over 40 runs, D-5.25); twice the time brings it to about 1; the sigma grows with
    it."""
    t0 = (0.1**2 / FLOOR**2) ** (1.0 / 3.0)
    assert math.isclose(t0, 5.10, abs_tol=0.01)
    n1, e1, s1 = channel_nees(0.1, t0, runs=12)
    n2, e2, s2 = channel_nees(0.1, 2.0 * t0, runs=12)
    assert 1.2 < n1 < 2.0
    assert 0.8 < n2 < 1.25
    assert s2 > s1 and e2 < e1 * 1.05
