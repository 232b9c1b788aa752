"""Headings in the CP window (ekf-vs-cp eq. (5)): gyro fixes meet every 2*pi branch of
what is known; with nothing known the first fix chooses the representation."""

from __future__ import annotations

import math

from localization.cp_window import SlidingWindowCP
from localization.interval import IV


def test_first_gyro_fix_on_an_unknown_heading_chooses_the_branch():
    w = SlidingWindowCP()
    w.start(0)
    w.heading(0, IV.around(0.5 + 6 * math.pi, 0.01))  # wrapped three turns away
    _, _, th = w.current()
    assert bool(th.contains(0.5)) and float(th.width()) < 0.03


def test_gyro_fix_meets_every_branch_of_a_wide_prior():
    w = SlidingWindowCP()
    w.start(0, th=IV.of(-10.0, 10.0))  # more than three turns of uncertainty
    w.heading(0, IV.around(0.5, 0.01))
    _, _, th = w.current()
    for k in (-1, 0, 1):  # every branch inside the prior is kept ...
        assert bool(th.contains(0.5 + 2 * math.pi * k))
    assert float(th.lo) > -10.0 and float(th.hi) < 10.0  # ... and the ends moved onto them
