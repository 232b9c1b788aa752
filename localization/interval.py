"""Guaranteed interval arithmetic on numpy arrays (ekf-vs-cp.txt §2.3, the tool that
solves eq. (5)): one import for the whole kit.

- ``localization.interval_arith``: the :class:`IV` arrays of intervals, outward-rounded
  + - * /, ``sqr``, ``sqrt`` and the backward projections ``bwd_sqr``, ``bwd_mul``;
- ``localization.interval_trig``: the periodic part (cos, sin, atan2 and ``bearing``, the chord factor
  ``sinc_half`` of eq. (2), ``bwd_cos``, ``bwd_sin``) and angles modulo 2*pi
  (``align_angle``, ``meet_angle``), every branch handled for boxes of any width.

Every operation contains every exact result on real points of its operands, for any
input box (wide, huge, tiny, denormal, unbounded); see the two modules for how.
"""

from __future__ import annotations

from localization.interval_arith import IV, as_iv, bwd_mul, bwd_sqr, down, sqr, sqrt, up
from localization.interval_trig import (
    HALF_PI,
    PI,
    TRANS_MARGIN,
    TWO_PI,
    TWO_PI_IV,
    align_angle,
    atan2,
    bearing,
    bwd_cos,
    bwd_sin,
    cos,
    meet_angle,
    sin,
    sinc_half,
)

__all__ = [
    "HALF_PI",
    "IV",
    "PI",
    "TRANS_MARGIN",
    "TWO_PI",
    "TWO_PI_IV",
    "align_angle",
    "as_iv",
    "atan2",
    "bearing",
    "bwd_cos",
    "bwd_mul",
    "bwd_sin",
    "bwd_sqr",
    "cos",
    "down",
    "meet_angle",
    "sin",
    "sinc_half",
    "sqr",
    "sqrt",
    "up",
]
