"""Whether to take the loop-closing correction of ir-grid-mapping §4, and the
re-alignment of the scans it moves.

When the sample cloud covers an earlier node (fig. 11 c), the samples are weighted with
the beam model of eq. 7-8 on the window's scans; the posterior's mean is the corrected
pose (fig. 11 d), and the range data are re-aligned and re-inserted (fig. 11 e, 12).
Beyond the paper, a correction must earn its place; the uncorrected branch is kept when

- the evidence is flat: the whole evidence leaves more than ``ess_max`` of the prior
  samples effective (outcome "weak": nothing was learnt);
- the posterior cannot be estimated from enough samples: the tempering
  (:func:`mapping.pose_samples.smc_posterior`) did not take the whole evidence in within
  ``max_stages``, or fewer than ``min_distinct`` distinct samples carry it (a likelihood
  so sharp or so ragged that a mean and a covariance would rest on a handful of samples;
  "weak");
- the uncorrected pose is plausible under the posterior: squared Mahalanobis distance
  below ``significance_d2`` (11.34 = chi-square 3 dof at 99 %; "confirmed");
- the corrected pose is not significantly better on the window: the tempered
  log-likelihood ratio Lambda of the corrected over the uncorrected pose, on the beams
  that see mapped space from both (a beam that looks into unmapped space from one pose
  is evidence for neither: a correction needs data that contradict the uncorrected
  pose, not just data that fit some other mapped wall), is below
  ``lr_min`` (5.67 nats: 2 Lambda >= chi-square 3 dof at 99 %, Wilks' threshold for a
  correction of three parameters fitted to the data; "worse").

A correction that passes is then only a candidate: :class:`HeldOut` runs a sequential
likelihood-ratio test of the corrected branch against the uncorrected one on the scans
that come *after* it (data the correction was not fitted to, matched against the same
map): accepted when the tempered log-likelihood ratio reaches ``confirm_nats`` (6.9:
1 in 1000) once at least ``confirm_min_m`` of travel (as much as the window the
correction was fitted on) has been scored, dropped ("unconfirmed") when it falls to
``reject_nats`` or after ``confirm_m`` of travel without a decision. Every check is reported as a :class:`msgs.AssociationReport`
with its reason.

Re-alignment (:func:`realigned_poses`): the heading correction is ramped in over the
span re-inserted (proportional to the distance travelled), the positions re-integrated
from the recorded steps, and the remaining position gap ramped in the same way, so the
pose at the start of the span is unchanged and the last one equals the corrected pose.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from mapping.association_config import AssociationConfig
from mapping.pose_samples import Posterior, smc_posterior
from mapping.se2 import compose, relative, wrap
from msgs import AssociationReport

LogLikelihood = Callable[[np.ndarray, np.ndarray, np.ndarray, np.ndarray], np.ndarray]
"""(poses (P, 3), sensor poses (M, 3), ranges (M,), kinds (M,)) -> log p(z | x, m) (P,)."""
PairRatio = Callable[[np.ndarray, np.ndarray], tuple[float, int]]
"""(pose a, pose b) -> (tempered log-likelihood ratio of a over b on the beams both see
observed space with, that count)."""


@dataclass(frozen=True)
class LoopCheck:
    """One check's report; with a candidate correction, the corrected pose and the
    posterior's samples."""

    report: AssociationReport
    corrected: np.ndarray | None = None
    posterior: Posterior | None = None


def check_loop(
    cfg: AssociationConfig,
    prior: np.ndarray,
    estimate: np.ndarray,
    window: tuple[np.ndarray, np.ndarray, np.ndarray],
    loglik: LogLikelihood,
    rng: np.random.Generator,
    node: int,
    stamp_ns: int,
    pair: PairRatio | None = None,
) -> LoopCheck:
    """Weigh the cloud ``prior`` on the ``window``'s beams (sensor poses, ranges, kinds)
    against the uncorrected pose ``estimate`` at ``node``; see the module doc. ``pair``
    gives the window's likelihood ratio of two poses (default: from ``loglik`` on every
    beam). A candidate comes back with outcome "candidate" (to be confirmed by
    :class:`HeldOut`)."""
    sens, ranges, kinds = window
    n = len(prior)

    def report(outcome: str, ess: float, lr: float, corr: np.ndarray | None, why: str):
        c = corr if corr is not None else np.zeros(3)
        return AssociationReport(stamp_ns, outcome, node, n, ess, lr, float(c[0]),
                                 float(c[1]), float(c[2]), reason=why)  # fmt: skip

    if len(kinds) == 0:
        return LoopCheck(report("weak", 1.0, 0.0, None, "no usable beams"))

    def ll(poses: np.ndarray) -> np.ndarray:
        return loglik(poses, sens, ranges, kinds)

    post = smc_posterior(prior, ll, cfg, rng)
    ess = post.ess_first
    if ess > cfg.ess_max:
        why = f"evidence too flat (ESS/N {ess:.2f} > {cfg.ess_max})"
        return LoopCheck(report("weak", ess, 0.0, None, why))
    if not post.resolved:
        why = (f"evidence too sharp for the cloud: not taken in within {cfg.max_stages} "
               f"tempering stages (ESS/N {ess:.3f})")  # fmt: skip
        return LoopCheck(report("weak", ess, 0.0, None, why))
    if post.distinct < cfg.min_distinct:
        why = (f"too few effective samples: the posterior rests on {post.distinct} distinct "
               f"of {n} (< {cfg.min_distinct}; ESS/N {ess:.3f}, MH acceptance "
               f"{post.accept:.2f})")  # fmt: skip
        return LoopCheck(report("weak", ess, 0.0, None, why))
    corr = correction(post.mean, estimate)
    if pair is not None:
        lr, _ = pair(post.mean, estimate)
    else:
        lr = likelihood_ratio(ll, post.mean, estimate, cfg)
    d2 = mahalanobis2_gauss(post.mean, post.cov, estimate)
    if d2 < cfg.significance_d2:
        why = (f"uncorrected pose inside the posterior (d2 {d2:.1f} < {cfg.significance_d2}, "
               f"{post.distinct} samples): kept")  # fmt: skip
        return LoopCheck(report("confirmed", ess, lr, corr, why), None, post)
    if lr < cfg.lr_min:
        why = (f"corrected pose not significantly better on the window (LR {lr:.1f} < "
               f"{cfg.lr_min} nats): uncorrected branch kept")  # fmt: skip
        return LoopCheck(report("worse", ess, lr, corr, why))
    why = (f"candidate: d2 {d2:.1f}, window LR {lr:.1f} nats, {post.distinct} samples, "
           f"{post.stages} stages")  # fmt: skip
    return LoopCheck(report("candidate", ess, lr, corr, why), post.mean.copy(), post)


def mahalanobis2_gauss(mean: np.ndarray, cov: np.ndarray, pose: np.ndarray) -> float:
    """Squared Mahalanobis distance of ``pose`` from N(mean, cov) (heading wrapped)."""
    dev = np.array([pose[0] - mean[0], pose[1] - mean[1], float(wrap(pose[2] - mean[2]))])
    c = cov + np.diag([1e-8, 1e-8, 1e-10])
    return float(dev @ np.linalg.solve(c, dev))


def likelihood_ratio(
    ll: Callable[[np.ndarray], np.ndarray], a: np.ndarray, b: np.ndarray, cfg: AssociationConfig
) -> float:
    """Tempered log-likelihood ratio of pose a over pose b (``ll``: poses -> log p)."""
    lab = ll(np.stack([a, b]))
    return float(lab[0] - lab[1]) / cfg.temperature


def correction(new: np.ndarray, old: np.ndarray) -> np.ndarray:
    """The change (dx, dy, dtheta) from pose ``old`` to pose ``new``."""
    return np.array([new[0] - old[0], new[1] - old[1], float(wrap(new[2] - old[2]))])


@dataclass
class HeldOut:
    """A candidate correction under test on the scans after it (module doc): the
    corrected branch is the candidate pose moved by the same odometry as the estimate."""

    check: LoopCheck
    base: np.ndarray  # the uncorrected estimate when the candidate was found
    travel0: float
    lam: float = 0.0
    scans: int = 0
    beams: int = 0

    def corrected(self, estimate: np.ndarray) -> np.ndarray:
        """The corrected branch's pose where the uncorrected one is ``estimate``."""
        assert self.check.corrected is not None
        return compose(self.check.corrected, relative(self.base, estimate))

    def score(self, estimate: np.ndarray, pair: PairRatio) -> None:
        """Add one new scan's tempered log-likelihood ratio of the corrected branch over
        the uncorrected one (``pair``: on that scan's beams)."""
        lr, n = pair(self.corrected(estimate), estimate)
        self.lam += lr
        self.scans += 1
        self.beams += n

    def decision(self, travel: float, cfg: AssociationConfig) -> str | None:
        """ "accepted", "unconfirmed" or None (go on)."""
        if self.lam >= cfg.confirm_nats and travel - self.travel0 >= cfg.confirm_min_m:
            return "accepted"
        if self.lam <= cfg.reject_nats or travel - self.travel0 >= cfg.confirm_m:
            return "unconfirmed"
        return None


def realigned_poses(poses: np.ndarray, travel: np.ndarray, corrected: np.ndarray) -> np.ndarray:
    """The poses (N, 3) of a span, taken at ``travel`` (N,), re-aligned so the first is
    unchanged and the last is ``corrected`` (fig. 11 e; see the module doc)."""
    span = travel[-1] - travel[0]
    f = (travel - travel[0]) / span if span > 1e-9 else np.ones(len(travel))
    dth = float(wrap(corrected[2] - poses[-1, 2]))
    steps = np.diff(poses[:, :2], axis=0)
    ang = f[1:] * dth
    c, s = np.cos(ang), np.sin(ang)
    rot = np.stack([c * steps[:, 0] - s * steps[:, 1], s * steps[:, 0] + c * steps[:, 1]], 1)
    xy = poses[0, :2] + np.concatenate([np.zeros((1, 2)), np.cumsum(rot, axis=0)])
    gap = corrected[:2] - xy[-1]
    xy = xy + f[:, None] * gap
    new = np.column_stack([xy, poses[:, 2] + f * dth])
    new[-1] = corrected
    return new
