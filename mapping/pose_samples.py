"""The sample cloud of ir-grid-mapping §4: the robot's pose as samples that spread as it
moves (fig. 9), weighted with the beam model of eq. 7-8, resampled and summarised.

- :func:`spread`: every sample moves by the odometry step plus its own noise; the
  heading noise grows with the distance and the turn (``heading_noise_*``) plus the
  growth of the heading filter's variance (the filter of eq. 1-4 treats the gyro's scale
  error as white and is overconfident over tens of metres; the cloud must cover the
  real error to find a node), the position noise with the distance;
- :func:`systematic`: systematic resampling;
- :func:`mean_std`: the weighted mean and spread (heading on the circle);
- :func:`smc_posterior`: the posterior by tempering (sequential Monte Carlo): the
  evidence taken in by steps that keep half the samples effective, with resampling and
  Metropolis-Hastings moves, so that the posterior's mean and covariance rest on many
  samples, not on the two or three a sharp likelihood leaves on the prior cloud.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

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


def mean_std(parts: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Weighted mean (heading: circular mean) and standard deviation of the samples."""
    mx = float(np.sum(w * parts[:, 0]))
    my = float(np.sum(w * parts[:, 1]))
    mt = float(np.angle(np.sum(w * np.exp(1j * parts[:, 2]))))
    dx, dy = parts[:, 0] - mx, parts[:, 1] - my
    dt = wrap(parts[:, 2] - mt)
    std = np.sqrt([np.sum(w * dx**2), np.sum(w * dy**2), np.sum(w * dt**2)])
    return np.array([mx, my, mt]), std


@dataclass(frozen=True)
class Posterior:
    """The samples' posterior after :func:`smc_posterior` (equal weights)."""

    samples: np.ndarray  # (N, 3)
    mean: np.ndarray  # (3,) heading: circular mean
    cov: np.ndarray  # (3, 3) from the N samples
    ess_first: float  # ESS / N of the whole evidence on the prior cloud
    stages: int  # tempering stages run
    distinct: int  # distinct samples at the end
    accept: float  # Metropolis-Hastings acceptance of the last stage's moves
    resolved: bool  # the whole evidence was taken in (beta reached 1)


def ess_fraction(a: np.ndarray) -> float:
    """Effective sample size over N of the weights exp(a) (a: log-weights)."""
    w = np.exp(a - a.max())
    w = w / w.sum()
    return float(1.0 / np.sum(w * w)) / len(a)


def _gauss(parts: np.ndarray, floor: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    mean, _ = mean_std(parts, np.full(len(parts), 1.0 / len(parts)))
    d = parts - mean
    d[:, 2] = wrap(d[:, 2])
    return mean, d.T @ d / len(parts) + np.diag(floor**2)


def smc_posterior(
    prior: np.ndarray,
    loglik: Callable[[np.ndarray], np.ndarray],
    cfg: AssociationConfig,
    rng: np.random.Generator,
) -> Posterior:
    """Samples of p(x | z) proportional to the prior cloud times exp(loglik / temperature),
    by tempering: the evidence is taken in by steps beta_k -> 1, each as large as keeps the
    effective sample size at half the samples, followed by systematic resampling and
    ``mh_moves`` Metropolis-Hastings moves (Gaussian steps scaled to the cloud, the prior
    taken as the Gaussian fitted to the prior cloud). At most ``max_stages`` stages; the
    posterior's mean and covariance come from all N samples at the end, so they rest on
    as many samples as moved there (``distinct``)."""
    n = len(prior)
    floor = np.array([0.01, 0.01, math.radians(0.2)])
    mu0, cov0 = _gauss(prior, floor)
    inv0 = np.linalg.inv(cov0)

    def logprior(x: np.ndarray) -> np.ndarray:
        d = x - mu0
        d[:, 2] = wrap(d[:, 2])
        return -0.5 * np.einsum("ij,jk,ik->i", d, inv0, d)

    x = prior.copy()
    ll = loglik(x) / cfg.temperature
    ess_first = ess_fraction(ll)
    beta, stages, accept = 0.0, 0, 1.0
    while beta < 1.0 and stages < cfg.max_stages:
        stages += 1
        db = 1.0 - beta
        if ess_fraction(db * ll) < 0.5:
            lo, hi = 0.0, db
            for _ in range(30):
                mid = 0.5 * (lo + hi)
                lo, hi = (mid, hi) if ess_fraction(mid * ll) >= 0.5 else (lo, mid)
            db = max(lo, 1e-12)
        beta = min(1.0, beta + db)
        a = db * ll
        w = np.exp(a - a.max())
        idx = systematic(w / w.sum(), rng)
        x, ll = x[idx], ll[idx]
        _, cov = _gauss(x, floor)
        chol = np.linalg.cholesky(cov * (2.38**2 / 3.0))
        lp = logprior(x)
        acc_n = 0
        for _ in range(cfg.mh_moves):
            prop = x + rng.normal(size=x.shape) @ chol.T
            llp = loglik(prop) / cfg.temperature
            lpp = logprior(prop)
            ok = np.log(rng.random(n)) < beta * (llp - ll) + lpp - lp
            x[ok], ll[ok], lp[ok] = prop[ok], llp[ok], lpp[ok]
            acc_n += int(ok.sum())
        accept = acc_n / (n * max(cfg.mh_moves, 1))
    mean, _ = mean_std(x, np.full(n, 1.0 / n))
    _, cov = _gauss(x, np.zeros(3))
    distinct = len(np.unique(np.round(x, 9), axis=0))
    return Posterior(x, mean, cov, ess_first, stages, distinct, accept, beta >= 1.0)
