"""hilnav.fleet.score.Track: a box against the truth, headings compared modulo 2 pi."""

from __future__ import annotations

import math

import numpy as np

from hilnav.fleet.score import Track

TWO_PI = 2 * math.pi


def test_a_box_holds_the_truth_whatever_turn_its_heading_is_written_in():
    t = Track()
    truth = np.array([1.0, 2.0, 0.25])
    for k in (-2, 0, 3):
        t.record([0.5, 1.5, 0.2 + k * TWO_PI], [1.5, 2.5, 0.3 + k * TWO_PI], truth)
    t.record((0.5, 1.5, 0.3), (1.5, 2.5, 0.4), truth)  # the heading misses
    t.record((1.1, 1.5, 0.2), (1.5, 2.5, 0.3), truth)  # x misses
    assert t.contained == [True, True, True, False, False]
    assert t.area_m2[:4] == [1.0] * 4 and math.isclose(t.area_m2[4], 0.4)
    assert t.lo[0] == (0.5, 1.5, 0.2 - 2 * TWO_PI) and all(type(v) is float for v in t.hi[0])
    # a heading bound at infinity: held when that side is open; an unknown heading is not
    # scored as held (the middle of the box is no heading)
    t.record((0.5, 1.5, 0.2), (1.5, 2.5, math.inf), truth)
    t.record((0.5, 1.5, -math.inf), (1.5, 2.5, math.inf), truth)
    assert t.contained[-2:] == [True, False]
    f = t.figures(0.1)
    assert f["contained"] == 4 and math.isclose(f["area"], 0.1 * sum(t.area_m2))
