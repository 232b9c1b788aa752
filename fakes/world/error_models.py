"""Error draws of the paper scenario against a stated bound b (fakes.world.paper_scenario).

Constraint propagation is guaranteed when every error lies inside the bound the localizer
assumes; these models say what happens when they do not. Each draws an error for a
sensor whose bound is b (per sample; b may vary, e.g. the wheels' abs + rel |dS|):

- ``uniform``: ``SHRINK * b * U(-1, 1)`` (SHRINK = 0.95, so float rounding cannot step
  outside): the set-membership assumption itself; never outside the bound.
- ``gaussian``: ``N(0, sigma = b / sqrt(3))``, the uniform's standard deviation: about
  8.3 % of the errors fall outside the bound (P(|z| > sqrt 3)).
- ``bias``: a constant offset of ``0.5 b`` plus the uniform draw. The offset's sign is
  drawn once per sensor channel (per robot: right wheel, left wheel, gyro, GPS east,
  GPS north; per ordered robot pair: range, bearing), so the error is stuck on one side,
  in ``[-0.45 b, 1.45 b]`` or its mirror: up to about 24 % outside the bound.
- ``heavy``: Student-t with nu = 3 degrees of freedom, scaled so that its median |error|
  equals the uniform draw's (``0.475 b``): the same typical error with heavy tails
  (about 21 % outside b, 1.7 % outside 3 b, 0.05 % outside 10 b). Real sensors look like
  this: MRCLAM's bearings have p99.9 / median of about 13, t_3's is 16.9.

``error(model, b, u, sign)`` maps a uniform draw ``u`` in [-1, 1) to the model's error
by its quantile function (the inverse CDF at (u + 1) / 2), so every model consumes the
same random numbers: one seed gives one world (the same truth, the same draws), and
each error is the uniform one moved to the same quantile of another distribution.
``sign`` is the bias channel's (+1 or -1, see :func:`bias_signs`).
"""

from __future__ import annotations

import numpy as np

ERROR_MODELS = ("uniform", "gaussian", "bias", "heavy")
SHRINK = 0.95  # uniform errors are drawn within SHRINK * bound
BIAS_FRACTION = 0.5
T_NU = 3.0
_P_MIN = 2.0**-53  # u = -1 would be the quantile 0: -inf (and 1 - _P_MIN < 1)
#: median of |t_3| = the 0.75 quantile of Student's t with 3 degrees of freedom
T3_MEDIAN_ABS = 0.7648923284043444
#: probability that |error| > the bound, per model (t_3: P(|t| > 0.7649 / 0.475))
OUTSIDE_BOUND = {"uniform": 0.0, "gaussian": 0.0833, "bias": 0.2368, "heavy": 0.2057}


def check_model(model: str) -> str:
    if model not in ERROR_MODELS:
        raise ValueError(f"error model {model!r}: choose one of {', '.join(ERROR_MODELS)}")
    return model


def error(
    model: str, bound: float | np.ndarray, u: float | np.ndarray, sign: float | np.ndarray = 1.0
) -> float | np.ndarray:
    """The error of ``model`` for a sensor bounded by ``bound``, at the uniform draw ``u``
    in [-1, 1) (see the module docstring)."""
    if model == "uniform":
        return SHRINK * bound * u
    if model == "bias":
        return sign * BIAS_FRACTION * bound + SHRINK * bound * u
    from scipy.special import ndtri, stdtrit

    p = np.clip(0.5 * (np.asarray(u, dtype=float) + 1.0), _P_MIN, 1.0 - _P_MIN)
    if model == "gaussian":
        return bound / np.sqrt(3.0) * ndtri(p)
    if model == "heavy":
        return 0.5 * SHRINK * bound / T3_MEDIAN_ABS * stdtrit(T_NU, p)
    raise ValueError(check_model(model))


def bias_signs(seed: int, key: int, channels: int) -> np.ndarray:
    """The bias model's fixed sign (+1 or -1) of each of ``channels`` sensor channels,
    from their own seeded stream (the error streams stay those of the other models)."""
    rng = np.random.default_rng([seed, key, 7919])
    return np.where(rng.uniform(size=channels) < 0.5, -1.0, 1.0)
