"""Error model of the fake GPS receiver: white noise, a slowly wandering bias, outages.

Horizontal error = bias(t) + white noise per axis. The bias is a first-order
Gauss-Markov process (correlation time ``bias_tau_s``), which is how a standalone
receiver's error wanders with satellite geometry and the ionosphere; outages start at a
rate per second and last an exponentially distributed time; rare multipath jumps add a
large offset to single fixes. Defaults are of a consumer receiver in open sky
(about 2.5 m CEP): white 0.5 m, bias 1.5 m with tau 120 s, HDOP about 1.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np


@dataclass
class GpsErrorModel:
    """Stateful error process of one receiver; ``sample`` advances it by ``dt``."""

    white_sigma_m: float = 0.5
    bias_sigma_m: float = 1.5
    bias_tau_s: float = 120.0
    vertical_factor: float = 1.7
    outage_rate_per_s: float = 0.0
    outage_mean_s: float = 10.0
    jump_prob: float = 0.0
    jump_sigma_m: float = 15.0
    hdop: float = 1.0
    seed: int = 0
    bias_m: np.ndarray = field(init=False)
    outage_left_s: float = field(init=False, default=0.0)

    def __post_init__(self) -> None:
        self._rng = np.random.default_rng(self.seed)
        self.bias_m = self._rng.normal(0.0, self.bias_sigma_m, size=3) * np.array(
            [1.0, 1.0, self.vertical_factor]
        )

    def sample(self, dt: float) -> np.ndarray | None:
        """Error (east, north, up) in metres of the next fix, or None during an outage."""
        a = math.exp(-dt / self.bias_tau_s)
        q = self.bias_sigma_m * math.sqrt(1.0 - a * a)
        self.bias_m = a * self.bias_m + self._rng.normal(0.0, q, size=3) * np.array(
            [1.0, 1.0, self.vertical_factor]
        )
        if self.outage_left_s > 0.0:
            self.outage_left_s -= dt
            return None
        if self.outage_rate_per_s > 0 and self._rng.random() < self.outage_rate_per_s * dt:
            self.outage_left_s = float(self._rng.exponential(self.outage_mean_s))
            return None
        err = self.bias_m + self._rng.normal(0.0, self.white_sigma_m, size=3) * np.array(
            [1.0, 1.0, self.vertical_factor]
        )
        if self.jump_prob > 0 and self._rng.random() < self.jump_prob:
            err[:2] += self._rng.normal(0.0, self.jump_sigma_m, size=2)
        return err

    @property
    def horizontal_sigma_m(self) -> float:
        """1-sigma per horizontal axis of bias plus white noise (what the fix should claim)."""
        return math.hypot(self.white_sigma_m, self.bias_sigma_m)
