"""Conversion factors of Pioneer robots (ARIA params/p3dx-sh.p, p3dx.p, ArRobotTypes.cpp)."""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class RobotParams:
    """Factors that turn ARCOS integers into SI units.

    dist_conv: mm per position unit; angle_conv: rad per heading unit (2 pi / 4096);
    vel_conv: mm/s per velocity unit; diff_conv: rad/s of rotation per mm/s of half the
    wheel speed difference (ARIA: rotvel = (R - L) / 2 * DiffConvFactor).
    """

    subclass: str = "p3dx-sh"
    dist_conv: float = 1.0
    angle_conv: float = 0.001534
    vel_conv: float = 1.0
    diff_conv: float = 0.0056
    vel2_divisor: int = 20
    range_conv: float = 1.0
    max_trans_vel_mmps: float = 1500.0
    max_rot_vel_degps: float = 360.0

    @property
    def wheelbase_m(self) -> float:
        """Wheel base implied by DiffConvFactor (about 0.357 m for a P3-DX)."""
        return 2.0 / self.diff_conv / 1000.0


P3DX_SH = RobotParams()
P3DX = RobotParams(subclass="p3dx", dist_conv=0.485)
KNOWN = {"p3dx-sh": P3DX_SH, "p3dx": P3DX, "p3dx-sh-lms": P3DX_SH}
TICKS_PER_TURN = 4096
ANGLE_UNIT_RAD = 2.0 * math.pi / TICKS_PER_TURN


def params_for(subclass: str) -> RobotParams:
    """Parameters of a subclass the robot announced; p3dx-sh for unknown ARCOS robots."""
    return KNOWN.get(subclass.lower(), P3DX_SH)
