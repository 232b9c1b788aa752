"""Error model of the fake CruzCore yaw gyro: bias, bias drift, white noise, scale factor.

measured_rate = (1 + scale_error) * true_rate + bias(t) + white noise, where bias(t) is
a constant turn-on bias plus a random walk (bias instability). Default figures are of
the CruzCore XG1010/R1050 class of MEMS yaw gyros (datasheet order of magnitude): rate
noise density 0.015 deg/s/sqrt(Hz) (so about 0.15 deg/s rms at 100 Hz), turn-on bias
up to 0.1 deg/s, bias random walk 0.002 deg/s/sqrt(s), scale factor error 0.5 %.
The angle the device integrates itself drifts by the bias: the driver and the heading
filter should trust the rate (or angle differences) over short intervals.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

DEG = math.pi / 180.0


@dataclass
class GyroErrorModel:
    """Stateful error process of one gyro; ``sample`` advances it by ``dt``."""

    noise_density_radps_rthz: float = 0.015 * DEG
    turn_on_bias_radps: float = 0.1 * DEG
    bias_walk_radps_rts: float = 0.002 * DEG
    scale_error: float = 0.005
    seed: int = 0
    bias_radps: float = field(init=False, default=0.0)
    scale: float = field(init=False, default=1.0)

    def __post_init__(self) -> None:
        self._rng = np.random.default_rng(self.seed)
        self.bias_radps = float(self._rng.normal(0.0, self.turn_on_bias_radps))
        self.scale = 1.0 + float(self._rng.normal(0.0, self.scale_error))

    def sample(self, true_rate_radps: float, dt: float) -> float:
        """One measured rate (rad/s) averaged over a sample period ``dt`` seconds."""
        self.bias_radps += float(self._rng.normal(0.0, self.bias_walk_radps_rts * math.sqrt(dt)))
        white = float(self._rng.normal(0.0, self.noise_density_radps_rthz / math.sqrt(dt)))
        return self.scale * true_rate_radps + self.bias_radps + white


def gyro_from_heading(
    t_s: np.ndarray, heading_rad: np.ndarray, model: GyroErrorModel, rate_hz: float = 100.0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A gyro emulated on a recorded heading (a data set's reference poses): samples every
    1 / ``rate_hz`` s over ``t_s``, the true rate being the slope of the (unwrapped)
    heading interpolated linearly, through ``model``'s errors. Returns (times s, measured
    rates rad/s, integrated angle rad: the device's own integration, from 0)."""
    t_s = np.asarray(t_s, dtype=float)
    if len(t_s) < 2 or not rate_hz > 0:
        return np.zeros(0), np.zeros(0), np.zeros(0)
    dt = 1.0 / rate_hz
    tg = t_s[0] + dt * np.arange(1, int((t_s[-1] - t_s[0]) / dt) + 1)
    th = np.interp(np.concatenate([[t_s[0]], tg]), t_s, np.unwrap(heading_rad))
    true_rate = np.diff(th) / dt
    rates = np.array([model.sample(float(w), dt) for w in true_rate])
    return tg, rates, np.cumsum(rates) * dt
