"""Joint Compatibility Branch and Bound (Neira & Tardos, 2001) for EKF-SLAM association.

Nearest neighbour judges each pairing alone, so two close landmarks seen with a common
pose error can be swapped. JCBB searches the interpretation tree for the hypothesis
with the most pairings whose *joint* innovation is compatible:
``nu_H' (H P H' + R)^-1 nu_H < chi2(2 |H|, alpha)``, using the correlations between the
landmarks (the joint H P H' comes from ``EkfSlam.joint_innovation_covariance``). Ties in
the number of pairings go to the smaller joint NIS. Branches are pruned by the bound
"pairings so far + observations left <= best"; a node budget bounds the worst case (the
best hypothesis found so far is returned when it runs out).
"""

from __future__ import annotations

import numpy as np
import scipy.linalg
import scipy.stats

from mapping.slam.association import CHI2_2DOF_99
from numerics.angles import wrap


def jcbb(
    z: np.ndarray,
    z_pred: np.ndarray,
    hph: np.ndarray,
    r: np.ndarray,
    d2: np.ndarray,
    gate: float = CHI2_2DOF_99,
    alpha: float = 0.99,
    max_nodes: int = 5000,
) -> np.ndarray:
    """Associate observations z (m, 2) with candidates z_pred (k, 2).

    hph: joint predicted-observation covariance (2k, 2k) without R; r: observation noise
    (2x2); d2: individual squared Mahalanobis distances (m, k) used for the individual
    gate ``gate`` and to order branches. Returns assoc (m,) of candidate columns or -1.
    """
    z = np.atleast_2d(z)
    m, k = d2.shape
    best: list[int] = [-1] * m
    if m == 0 or k == 0:
        return np.array(best, dtype=int)
    thresholds = scipy.stats.chi2.ppf(alpha, 2 * np.arange(1, m + 1))
    cands = [list(np.argsort(d2[i])[: int(np.count_nonzero(d2[i] < gate))]) for i in range(m)]
    state = {"best": best, "best_pairs": 0, "best_nis": np.inf, "nodes": 0}

    def joint_nis(pairs: list[tuple[int, int]]) -> float:
        oi = np.array([p[0] for p in pairs])
        lj = np.array([p[1] for p in pairs])
        nu = z[oi] - z_pred[lj]
        nu[:, 1] = wrap(nu[:, 1])
        rows = np.stack([2 * lj, 2 * lj + 1], axis=1).ravel()
        s = hph[np.ix_(rows, rows)] + np.kron(np.eye(len(pairs)), r)
        try:
            cho = scipy.linalg.cho_factor(s, lower=True, check_finite=False)
        except np.linalg.LinAlgError:
            return np.inf
        v = nu.ravel()
        return float(v @ scipy.linalg.cho_solve(cho, v, check_finite=False))

    def rec(i: int, hyp: list[int], pairs: list[tuple[int, int]], nis: float) -> None:
        if state["nodes"] >= max_nodes:
            return
        state["nodes"] += 1
        if i == m:
            n = len(pairs)
            if n > state["best_pairs"] or (n == state["best_pairs"] and nis < state["best_nis"]):
                state.update(best=list(hyp), best_pairs=n, best_nis=nis)
            return
        used = {p[1] for p in pairs}
        for j in cands[i]:
            if j in used:
                continue
            trial = pairs + [(i, int(j))]
            d = joint_nis(trial)
            if d < thresholds[len(trial) - 1]:
                rec(i + 1, hyp[:i] + [int(j)] + hyp[i + 1 :], trial, d)
        if len(pairs) + (m - i - 1) > state["best_pairs"]:
            rec(i + 1, hyp, pairs, nis)

    rec(0, [-1] * m, [], 0.0)
    return np.array(state["best"], dtype=int)
