"""Parameters of the encoder + gyro heading filter (fusion.heading; ir-grid-mapping eq.
1-4): the paper's alpha, beta, gamma read per distance and per turn, the priors of the
systematic terms (wheel-diameter and track-width errors, gyro scale and residual bias),
and the gyro handling of the alignment front end (fusion.alignment)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

DEG = math.pi / 180.0


@dataclass(frozen=True)
class HeadingParams:
    """Parameters of the heading filter (fusion.heading's module doc). Defaults: the
    paper's eq. 4 figures, read per distance and per turn; the systematic priors are 0
    here (the paper's model), the robot config's [noise] sets them for the daemon."""

    alpha_rad_per_m: float = 3.0 * DEG
    beta: float = 0.1
    gamma: float = 0.02
    initial_sigma_rad: float = 0.1 * DEG
    model: Literal["increment", "paper"] = "increment"
    # Systematic errors (0 = none): prior sigmas, and the calibrated encoder bias.
    encoder_bias_sigma_rad_per_m: float = 0.0
    encoder_bias_rad_per_m: float = 0.0
    track_scale_sigma: float = 0.0
    gyro_scale_sigma: float = 0.0
    learn_systematic: bool = True
    # Extras beyond eq. (4), 0 = the paper's model:
    gyro_arw_rad_per_sqrt_s: float = 0.0
    gyro_bias_sigma_radps: float = 0.0
    gyro_bias_walk_radps_per_sqrt_s: float = 0.0
    # Gyro handling:
    gyro_timeout_s: float = 0.5
    gyro_max_lag_s: float = 0.05
    gyro_max_defer_s: float = 2.0
    gyro_gate_probability: float | None = 0.9999
    learn_bias_at_rest: bool = True
    bias_window_s: float = 30.0
    bias_min_rest_s: float = 0.5
    variance_floor_rad2: float = 1e-18

    def __post_init__(self) -> None:
        for name in ("alpha_rad_per_m", "beta", "gamma", "initial_sigma_rad",
                     "encoder_bias_sigma_rad_per_m", "track_scale_sigma", "gyro_scale_sigma",
                     "gyro_arw_rad_per_sqrt_s", "gyro_bias_sigma_radps",
                     "gyro_bias_walk_radps_per_sqrt_s", "gyro_timeout_s",
                     "gyro_max_lag_s", "gyro_max_defer_s", "bias_window_s", "bias_min_rest_s"):  # fmt: skip
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0.0):
                raise ValueError(f"HeadingParams.{name} must be finite and >= 0, got {v!r}")
        if not math.isfinite(self.encoder_bias_rad_per_m):
            raise ValueError("HeadingParams.encoder_bias_rad_per_m must be finite")
        g = self.gyro_gate_probability
        if g is not None and not 0.0 < g < 1.0:
            raise ValueError(f"HeadingParams.gyro_gate_probability must be in (0, 1), got {g!r}")
        if self.model not in ("increment", "paper"):
            raise ValueError(
                f"HeadingParams.model must be 'increment' or 'paper', got {self.model!r}"
            )
