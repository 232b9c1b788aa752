"""The sample cloud of ir-grid-mapping §4: the robot's pose as samples that spread as it
moves (fig. 9), weighted with the beam model of eq. 7-8, resampled and summarised.

- :func:`spread`: every sample moves by the odometry step plus its own noise; the
  heading noise grows with the distance and the turn (``heading_noise_*``) plus the
  growth of the heading filter's variance (the filter of eq. 1-4 treats the gyro's scale
  error as white and is overconfident over tens of metres; the cloud must cover the
  real error to find a node), the position noise with the distance;
- :func:`tempered_weights`: normalised weights from the log-likelihood of eq. 7
  divided by ``temperature`` (nearby beams are not independent);
- :func:`systematic`: systematic resampling;
- :func:`anneal`: ``refine_rounds`` of resampling, a shrinking jitter and re-weighting,
  which sharpens the estimate from few samples;
- :func:`mean_std`, :func:`mahalanobis2`: the weighted mean and spread (heading on the
  circle), and the squared Mahalanobis distance of a pose from the weighted cloud.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from mapping.association_config import AssociationConfig
from mapping.se2 import compose, wrap


def spread(
    particles: np.ndarray,
    rel: np.ndarray,
    d: float,
    dvar: float,
    cfg: AssociationConfig,
    rng: np.random.Generator,
) -> np.ndarray:
    """The cloud moved by the step ``rel`` (robot frame, ``d`` metres long) with noise;
    ``dvar`` is the growth of the heading filter's variance over the step."""
    n = len(particles)
    sth = math.sqrt(
        cfg.heading_noise_rad_per_sqrt_m**2 * d
        + cfg.heading_noise_per_sqrt_rad**2 * abs(rel[2])
        + dvar
    )
    spos = cfg.position_noise_m_per_sqrt_m * math.sqrt(d)
    noisy = np.empty((n, 3))
    noisy[:, 0] = rel[0] + rng.normal(0.0, spos, n)
    noisy[:, 1] = rel[1] + rng.normal(0.0, spos, n)
    noisy[:, 2] = rel[2] + rng.normal(0.0, sth, n)
    return compose(particles, noisy)


def systematic(weights: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Indices of a systematic resampling of normalised ``weights``."""
    n = len(weights)
    pos = (rng.random() + np.arange(n)) / n
    return np.minimum(np.searchsorted(np.cumsum(weights), pos), n - 1)


def tempered_weights(ll: np.ndarray, temperature: float) -> np.ndarray:
    """Normalised weights exp(ll / temperature)."""
    a = ll / temperature
    w = np.exp(a - a.max())
    return w / w.sum()


def anneal(
    parts: np.ndarray,
    weights: np.ndarray,
    loglik: Callable[[np.ndarray], np.ndarray],
    cfg: AssociationConfig,
    rng: np.random.Generator,
) -> tuple[np.ndarray, np.ndarray]:
    """``refine_rounds`` of resampling, jitter (half the weighted spread, at least 1 cm
    and 0.2 deg) and re-weighting with ``loglik`` (poses (P, 3) -> log-likelihoods)."""
    for _ in range(cfg.refine_rounds):
        _, std = mean_std(parts, weights)
        parts = parts[systematic(weights, rng)]
        jit = np.maximum(0.5 * std, [0.01, 0.01, math.radians(0.2)])
        parts = parts + rng.normal(0.0, 1.0, parts.shape) * jit
        weights = tempered_weights(loglik(parts), cfg.temperature)
    return parts, weights


def mean_std(parts: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Weighted mean (heading: circular mean) and standard deviation of the samples."""
    mx = float(np.sum(w * parts[:, 0]))
    my = float(np.sum(w * parts[:, 1]))
    mt = float(np.angle(np.sum(w * np.exp(1j * parts[:, 2]))))
    dx, dy = parts[:, 0] - mx, parts[:, 1] - my
    dt = wrap(parts[:, 2] - mt)
    std = np.sqrt([np.sum(w * dx**2), np.sum(w * dy**2), np.sum(w * dt**2)])
    return np.array([mx, my, mt]), std


def mahalanobis2(parts: np.ndarray, w: np.ndarray, pose: np.ndarray) -> float:
    """Squared Mahalanobis distance of ``pose`` from the weighted samples' mean."""
    mean, _ = mean_std(parts, w)
    d = parts - mean
    d[:, 2] = wrap(d[:, 2])
    cov = (w[:, None] * d).T @ d + np.diag([1e-6, 1e-6, 1e-8])
    dev = np.array([pose[0] - mean[0], pose[1] - mean[1], float(wrap(pose[2] - mean[2]))])
    return float(dev @ np.linalg.solve(cov, dev))
