"""Whether to take the loop-closing correction of ir-grid-mapping §4, and the
re-alignment of the scans it moves.

When the sample cloud covers an earlier node (fig. 11 c), the samples are weighted with
the beam model of eq. 7-8 on the window's scans; their weighted mean is the corrected
pose (fig. 11 d), and the range data taken since the last correction are re-aligned and
re-inserted (fig. 11 e, 12). Beyond the paper, the map is never made worse: the
uncorrected branch is kept when

- the evidence is flat: effective sample size over sample count above ``ess_max``
  (outcome "weak");
- the uncorrected pose is plausible under the importance-weighted posterior of the
  prior cloud: squared Mahalanobis distance below ``significance_d2`` (11.34 =
  chi-square 3 dof at 99 %; outcome "confirmed"). The annealed estimate alone would
  overfit the noise and move an undrifted pose;
- the corrected pose does not explain the window better than the uncorrected one by
  ``lr_min`` nats (tempered log-likelihood ratio; outcome "worse").

Otherwise the correction is "accepted". Every check is reported as a
:class:`msgs.AssociationReport` with its reason.

Re-alignment (:func:`realigned_poses`): the heading correction is ramped in over the
span since the last correction (proportional to the distance travelled), the positions
re-integrated from the recorded steps, and the remaining position gap ramped in the same
way, so the pose at the start of the span is unchanged and the last one equals the
corrected pose.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from mapping.association_config import AssociationConfig
from mapping.pose_samples import anneal, mahalanobis2, mean_std, systematic, tempered_weights
from mapping.se2 import wrap
from msgs import AssociationReport

LogLikelihood = Callable[[np.ndarray, np.ndarray, np.ndarray, np.ndarray], np.ndarray]
"""(poses (P, 3), sensor poses (M, 3), ranges (M,), kinds (M,)) -> log p(z | x, m) (P,)."""


@dataclass(frozen=True)
class LoopCheck:
    """One check's report (``realigned_scans`` left 0) and, when the correction is
    accepted, the corrected pose and the resampled cloud."""

    report: AssociationReport
    corrected: np.ndarray | None = None
    particles: np.ndarray | None = None


def check_loop(
    cfg: AssociationConfig,
    prior: np.ndarray,
    estimate: np.ndarray,
    window: tuple[np.ndarray, np.ndarray, np.ndarray],
    loglik: LogLikelihood,
    rng: np.random.Generator,
    node: int,
    stamp_ns: int,
) -> LoopCheck:
    """Weigh the cloud ``prior`` on the ``window``'s beams (sensor poses, ranges, kinds)
    against the uncorrected pose ``estimate`` at ``node``; see the module doc."""
    sens, ranges, kinds = window
    n = len(prior)
    if len(kinds) == 0:
        return LoopCheck(
            AssociationReport(stamp_ns, "weak", node, n, 1.0, 0.0, reason="no usable beams")
        )

    def ll(poses: np.ndarray) -> np.ndarray:
        return loglik(poses, sens, ranges, kinds)

    w = tempered_weights(ll(prior), cfg.temperature)
    ess = float(1.0 / np.sum(w**2)) / n
    if ess > cfg.ess_max:
        return LoopCheck(AssociationReport(
            stamp_ns, "weak", node, n, ess, 0.0,
            reason=f"evidence too flat (ESS/N {ess:.2f} > {cfg.ess_max})",
        ))  # fmt: skip
    mean0, _ = mean_std(prior, w)
    d2 = mahalanobis2(prior, w, estimate)
    if d2 < cfg.significance_d2:
        # The uncorrected pose is plausible under the posterior: keep it, and leave the
        # cloud as it was (resampling on biased evidence would drag it away).
        corr = correction(mean0, estimate)
        return LoopCheck(AssociationReport(
            stamp_ns, "confirmed", node, n, ess, likelihood_ratio(ll, mean0, estimate, cfg),
            float(corr[0]), float(corr[1]), float(corr[2]),
            reason=f"uncorrected pose inside the posterior (d2 {d2:.1f} < "
            f"{cfg.significance_d2}): kept",
        ))  # fmt: skip
    parts, weights = anneal(prior, w, ll, cfg, rng)
    mean, _ = mean_std(parts, weights)
    lr = likelihood_ratio(ll, mean, estimate, cfg)
    corr = correction(mean, estimate)
    if lr < cfg.lr_min:
        return LoopCheck(AssociationReport(
            stamp_ns, "worse", node, n, ess, lr, float(corr[0]), float(corr[1]),
            float(corr[2]),
            reason=f"corrected pose not better by {cfg.lr_min} nats: uncorrected branch kept",
        ))  # fmt: skip
    report = AssociationReport(
        stamp_ns, "accepted", node, n, ess, lr, float(corr[0]), float(corr[1]), float(corr[2])
    )
    return LoopCheck(report, mean, parts[systematic(weights, rng)])


def likelihood_ratio(
    ll: Callable[[np.ndarray], np.ndarray], a: np.ndarray, b: np.ndarray, cfg: AssociationConfig
) -> float:
    """Tempered log-likelihood ratio of pose a over pose b (``ll``: poses -> log p)."""
    lab = ll(np.stack([a, b]))
    return float(lab[0] - lab[1]) / cfg.temperature


def correction(new: np.ndarray, old: np.ndarray) -> np.ndarray:
    """The change (dx, dy, dtheta) from pose ``old`` to pose ``new``."""
    return np.array([new[0] - old[0], new[1] - old[1], float(wrap(new[2] - old[2]))])


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
