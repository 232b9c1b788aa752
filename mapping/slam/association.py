"""Data association for EKF-SLAM (which slam-ekf.txt §1 leaves out; real data needs it).

- :func:`mahalanobis_matrix`: squared Mahalanobis distance of every observation to every
  predicted landmark observation, vectorised (m x k at once, closed-form 2x2 inverses).
- :func:`nearest_neighbour`: individual gating (chi-square, 2 dof) and greedy unique
  nearest-neighbour assignment (smallest distance first; a landmark takes at most one
  observation per scan).
- :func:`classify_unmatched`: the new-landmark threshold: an unmatched observation is a
  candidate for a *new* landmark only if it is farther than ``new_chi2`` from every known
  one; in between the gate and that threshold it is ambiguous and dropped.
- :class:`TentativeLandmarks`: candidates live outside the filter state until seen
  ``confirm_after`` times (matched in the world frame with a Mahalanobis gate), so one
  spurious detection never enters the map; stale candidates expire.

The joint-compatibility alternative to nearest neighbour is in ``jcbb.py``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from numerics.angles import wrap

#: chi-square quantiles, 2 degrees of freedom.
CHI2_2DOF_95 = 5.991
CHI2_2DOF_99 = 9.210
CHI2_2DOF_999 = 13.816


def inv2(s: np.ndarray) -> np.ndarray:
    """Inverses of a stack of 2x2 matrices (..., 2, 2), closed form."""
    det = s[..., 0, 0] * s[..., 1, 1] - s[..., 0, 1] * s[..., 1, 0]
    out = np.empty_like(s)
    out[..., 0, 0] = s[..., 1, 1]
    out[..., 1, 1] = s[..., 0, 0]
    out[..., 0, 1] = -s[..., 0, 1]
    out[..., 1, 0] = -s[..., 1, 0]
    return out / det[..., None, None]


def mahalanobis_matrix(
    z: np.ndarray, z_pred: np.ndarray, s: np.ndarray, angular: tuple[bool, bool] = (False, True)
) -> np.ndarray:
    """d2[i, j] = nu' S_j^-1 nu with nu = z_i - z_pred_j (components flagged ``angular``
    wrapped). z (m, 2), z_pred (k, 2), s (k, 2, 2) -> (m, k)."""
    z = np.atleast_2d(z)
    nu = z[:, None, :] - z_pred[None, :, :]
    for c, ang in enumerate(angular):
        if ang:
            nu[..., c] = wrap(nu[..., c])
    s00, s01, s10, s11 = s[:, 0, 0], s[:, 0, 1], s[:, 1, 0], s[:, 1, 1]
    n0, n1 = nu[..., 0], nu[..., 1]
    # nu' S^-1 nu with the closed-form inverse: (n0^2 s11 - n0 n1 (s01 + s10) + n1^2 s00) / det
    return (n0 * (n0 * s11 - n1 * (s01 + s10)) + n1 * n1 * s00) / (s00 * s11 - s01 * s10)


def nearest_neighbour(d2: np.ndarray, gate: float = CHI2_2DOF_99) -> np.ndarray:
    """Greedy unique NN: assoc[i] = landmark column of observation i, or -1."""
    m, k = d2.shape
    assoc = np.full(m, -1, dtype=int)
    if m == 0 or k == 0:
        return assoc
    obs, lms = np.nonzero(d2 < gate)
    order = np.argsort(d2[obs, lms], kind="stable")
    used_o = np.zeros(m, dtype=bool)
    used_l = np.zeros(k, dtype=bool)
    for t in order:
        i, j = obs[t], lms[t]
        if used_o[i] or used_l[j]:
            continue
        assoc[i] = j
        used_o[i] = used_l[j] = True
    return assoc


def classify_unmatched(
    d2: np.ndarray, assoc: np.ndarray, new_chi2: float = CHI2_2DOF_999
) -> np.ndarray:
    """Boolean mask of unmatched observations far enough from every landmark to be new."""
    far = (d2 > new_chi2).all(axis=1) if d2.shape[1] else np.ones(d2.shape[0], dtype=bool)
    return (assoc < 0) & far


@dataclass
class TentativeLandmarks:
    """Candidate landmarks kept outside the filter until confirmed.

    A candidate is a world position with a 2x2 covariance, a sighting count and the
    index of the scan it was last seen in. ``observe`` matches new world-frame
    detections to candidates (greedy NN, Mahalanobis gate ``gate`` on the summed
    covariances), fuses matched positions, creates candidates from the rest, and returns
    which detections confirmed a candidate (count reached ``confirm_after``); confirmed
    candidates leave the list. Candidates not seen for ``max_age_scans`` scans expire.
    """

    confirm_after: int = 3
    max_age_scans: int = 20
    gate: float = CHI2_2DOF_99
    pos: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    cov: np.ndarray = field(default_factory=lambda: np.zeros((0, 2, 2)))
    count: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    last: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    expired: int = 0

    def __len__(self) -> int:
        return len(self.pos)

    def observe(self, pos: np.ndarray, cov: np.ndarray, scan: int) -> np.ndarray:
        """Feed detections at world positions pos (k, 2) with covariances cov (k, 2, 2)
        in scan number ``scan``; returns a boolean mask of detections to promote now."""
        pos = np.atleast_2d(np.asarray(pos, float)).reshape(-1, 2)
        cov = np.asarray(cov, float).reshape(-1, 2, 2)
        promote = np.zeros(len(pos), dtype=bool)
        if self.confirm_after <= 1:
            promote[:] = True
            return promote
        assoc = np.full(len(pos), -1, dtype=int)
        if len(self.pos) and len(pos):
            d = pos[:, None, :] - self.pos[None, :, :]
            si = inv2(cov[:, None] + self.cov[None, :])
            d2 = np.einsum("mki,mkij,mkj->mk", d, si, d)
            assoc = nearest_neighbour(d2, self.gate)
        for i in np.nonzero(assoc >= 0)[0]:
            j = assoc[i]
            # fuse the two position estimates (information form)
            a = inv2(self.cov[j])
            b = inv2(cov[i])
            c = inv2(a + b)
            self.pos[j] = c @ (a @ self.pos[j] + b @ pos[i])
            self.cov[j] = c
            self.count[j] += 1
            self.last[j] = scan
        confirmed = np.zeros(len(self.pos), dtype=bool)
        for i in np.nonzero(assoc >= 0)[0]:
            if self.count[assoc[i]] >= self.confirm_after:
                promote[i] = True
                confirmed[assoc[i]] = True
        fresh = assoc < 0
        stale = (scan - self.last) > self.max_age_scans
        self.expired += int(np.count_nonzero(stale & ~confirmed))
        keep = ~(confirmed | stale)
        self.pos = np.concatenate([self.pos[keep], pos[fresh]])
        self.cov = np.concatenate([self.cov[keep], cov[fresh]])
        self.count = np.concatenate([self.count[keep], np.ones(fresh.sum(), dtype=int)])
        self.last = np.concatenate([self.last[keep], np.full(fresh.sum(), scan, dtype=int)])
        return promote
