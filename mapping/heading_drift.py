"""The systematic heading drift of the association's input, tested on the map (beyond
ir-grid-mapping §4).

The heading filter (:mod:`fusion.heading`) learns the encoders' systematic terms from the
gyro, but not the gyro's own scale error: the gyro measures every turn with it, and the
encoders' track-width error is only known relative to it. What is left turns the heading
by the same fraction of every turn, e = s T after a signed turn T (rad); the filter's
variance says so (its sigma grows with T, not with its square root), but no sensor on the
robot can tell s. The map can. It cannot do so one window at a time: in loops the map is
drawn with the drift, so a loop closure sees the map of the previous pass, a few degrees
off, and a few degrees are not significant on 1.5 m of six IR beams.

:class:`DriftBank` tests the drift as hypotheses fixed in advance, each with its own map:

- the branches: s_k = s_hat + spacing * m, m in ``drift_steps`` (-3, -1.5, 1.5, 3); the
  spacing is the prior sigma ``drift_sigma_per_rad`` (the gyro's scale sigma) at first,
  so the bank covers the prior's 99.7 %;
- a branch dead-reckons the input's steps from the bank's start with their heading
  changes scaled by 1 - s_k (the input turns by (1 + s) times the true turn), and keeps
  its own reference map: the scans older than ``ref_lag_m`` at the branch's poses (at
  the association's before the start). The null hypothesis is the association's own
  branch (s_hat, its reference map). A drift moves every pose since the start, and its
  evidence is the consistency of the map where the robot comes back, which only a map
  drawn at the branch's poses shows;
- one scan per ``window_m / window_scans`` of travel (the window's own spacing, for the
  layout's number of sensors) is scored
  against each branch's reference map at the branch's pose, on the beams that see mapped
  space in every branch's map: x_k, the tempered log-likelihood ratio of branch k over
  the null. The hypotheses were fixed before the data: nothing is fitted;
- the tempered ratios are not exact likelihood ratios (correlated beams, an approximate
  map), and their plain sums random-walk far on drift-free runs. Each scan counts with
  :func:`log_evalue` (an e-value valid whatever the ratios' scale), summed as a CUSUM
  reflected at ``reject_nats`` (a branch that falls behind before the robot closes a
  loop is not buried by it); a branch is adopted when it reaches ``confirm_nats`` + ln K
  (Ville's bound, Bonferroni over the K branches).

On adoption the association takes the branch's poses since the start, its reference map
and its pose, and dead-reckons with s_hat = s_k from then on, so later windows start
closer; a new bank starts around it, with half the spacing if the winner was inside the
bank (the truth lies within half a spacing of it), the same beyond one at its edge. A
correction of the association's own (the re-insertion changes its poses) restarts the
bank, whose null must be the association's branch.

Cost: K reference maps and K insertions of each scan as it ages (the same scans as the
association's reference map, within what is left of the step's budget), and K + 1 ray
casts of one scan per window spacing. The scans before the start go in at the same
poses for every branch: until the first scan after it comes of age the branches share
one map (copied when they part). The K insertions of a scan share the lattice of its
cones (``IrInverseModel.integrate_each``), and none goes through the memo of the
association's maps (other poses: never asked for again). Bit for bit what K maps of
their own, each inserting alone, give. The maps are filled as the scans age, not when a
score reads them: every scan that came of age between two scores has cells on the next
score's rays, so deferring scans would skip only a run's tail (``bench/branch_reads.py``,
docs/benchmarks.md); most cells are never read, but only a per-cell lazy map could skip
them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from mapping.association_config import AssociationConfig
from mapping.beam_model import BeamModel
from mapping.grid import OccupancyGrid
from mapping.ir_inverse import IrInverseModel
from mapping.loop_correction import correction
from mapping.scan_records import ScanRecords
from mapping.se2 import compose, relative
from msgs import AssociationReport


def log_evalue(x: float) -> float:
    """ln of the e-value of one scan's tempered log-likelihood ratio ``x``: theta x -
    theta^2 x^2 / 2 with theta = 1/2. For a ratio distributed symmetrically about zero
    (a wrong branch that fits as well as the null), exp of it has expectation <= 1
    whatever the ratio's scale (de la Pena's self-normalised supermartingale), and less
    for a branch that fits worse (a mean below zero; for Gaussian ratios at any spread),
    so the product over scans is a test supermartingale: it reaches 1 / alpha with
    probability <= alpha (Ville). theta = 1/2 is the growth-optimal choice were the
    ratios exact (mean d^2 / 2, variance d^2)."""
    return 0.5 * x - 0.125 * x * x


def drifted_step(rel: np.ndarray, drift: float) -> np.ndarray:
    """The input's step ``rel`` (dx, dy, dtheta in the previous frame) with its heading
    change corrected for a drift of ``drift`` per radian turned."""
    return np.array([rel[0], rel[1], rel[2] * (1.0 - drift)])


@dataclass
class Branch:
    """One drift hypothesis: its pose, its poses since the bank's start, its reference
    map and the CUSUM of its log-likelihood ratio over the null."""

    drift: float
    step: float  # drift = the bank's centre + step * spacing
    pose: np.ndarray
    ref: OccupancyGrid
    poses: list[np.ndarray] = field(default_factory=list)
    lam: float = 0.0


@dataclass(frozen=True)
class Adoption:
    """A branch that passed: its drift, its poses from scan ``start`` on, its pose and
    reference map, the statistic and the scans it rests on."""

    branch: Branch
    start: int
    lam: float
    threshold: float
    scans: int
    beams: int

    def rebase(
        self,
        rec: ScanRecords,
        particles: np.ndarray,
        old: np.ndarray,
        snaps: list[tuple[int, float, OccupancyGrid]],
        ref_upto: int,
        travel: float,
    ) -> tuple[np.ndarray, list[tuple[int, float, OccupancyGrid]]]:
        """The association takes the branch: its poses go into the records from the
        start; the cloud moves as the pose does (from ``old`` to the branch's); the map
        snapshots after the start (old poses) are dropped and the branch's reference map
        becomes one (it holds the scans before ``ref_upto`` at the new poses). Returns
        the cloud and the snapshots."""
        b = self.branch
        for i in range(self.start, len(rec)):
            rec.poses[i] = b.poses[i - self.start]
        move = compose(b.pose, relative(old, np.zeros(3)))  # old pose -> branch pose
        at = rec.travel[ref_upto] if ref_upto < len(rec) else travel
        kept = [sn for sn in snaps if sn[0] <= self.start] + [(ref_upto, at, b.ref.copy())]
        moved = compose(np.broadcast_to(move, particles.shape), particles)
        return moved, sorted(kept, key=lambda sn: sn[0])

    def next_spacing(self, spacing: float, steps: tuple[float, ...]) -> float:
        """The spacing of the next bank: the truth lies within half a spacing of a
        winner inside the bank; beyond a winner at its edge, it is kept."""
        edge = abs(self.branch.step) >= max(abs(m) for m in steps)
        return spacing if edge else 0.5 * spacing

    def report(
        self, stamp_ns: int, prev: float, old: np.ndarray, samples: int, n: int
    ) -> AssociationReport:
        """The report of its adoption (outcome "drift"): ``prev`` the drift before,
        ``old`` the association's pose before, ``n`` the scans recorded."""
        b, k = self.branch, n - self.start
        c = correction(b.pose, old)
        why = (f"heading drift {100 * b.drift:+.2f} % per radian turned (was {100 * prev:+.2f} "
               f"%): held-out evidence {self.lam:.1f} nats >= {self.threshold:.1f} (ln 1000 + "
               f"ln of the hypotheses) over {self.scans} scans ({self.beams} beams) against "
               f"the uncorrected branch, each on its own map; {k} scans re-aligned")  # fmt: skip
        return AssociationReport(stamp_ns, "drift", -1, samples, 0.0, self.lam, float(c[0]),
                                 float(c[1]), float(c[2]), k, reason=why)  # fmt: skip


class DriftBank:
    """The drift hypotheses around ``drift`` (module doc), started at scan ``start``
    (the next scan recorded) from ``pose`` and the reference map ``ref`` (holding the
    scans before ``ref_upto``), for a robot with ``mounts`` IR sensors."""

    def __init__(
        self,
        cfg: AssociationConfig,
        drift: float,
        spacing: float,
        start: int,
        pose: np.ndarray,
        ref: OccupancyGrid,
        ref_upto: int,
        next_travel: float = 0.0,
        *,
        mounts: int,
    ) -> None:
        self.cfg = cfg
        self.window_scans = cfg.window_scans(mounts)  # the scored scans' spacing
        self.drift, self.spacing, self.start = drift, spacing, start
        # Until the first scan after the start comes of age every branch's map takes the
        # same scans at the same poses: one map, shared, copied when they part (exact).
        shared = ref.copy()
        self.branches = [Branch(drift + spacing * m, m, np.array(pose, dtype=float), shared)
                         for m in cfg.drift_steps]  # fmt: skip
        self.shared = True
        self.ref_upto = ref_upto
        self.threshold = cfg.confirm_nats + math.log(max(len(self.branches), 1))
        self.next_travel = next_travel
        self.scans = 0
        self.beams = 0

    def move(self, rel: np.ndarray) -> None:
        """Dead-reckon every branch by the input's step ``rel``."""
        for b in self.branches:
            b.pose = compose(b.pose, drifted_step(rel, b.drift))

    def record(self) -> None:
        """The scan just recorded was taken at every branch's current pose."""
        for b in self.branches:
            b.poses.append(b.pose.copy())

    def age(self, rec: ScanRecords, upto: int, model: IrInverseModel, per_branch: int) -> int:
        """Insert the next scans up to ``upto`` (where the association's reference map has
        got to), at most ``per_branch`` of them, into every branch's reference map;
        returns the cell updates. Until it has caught up no scan is scored (the maps
        compared must hold the same scans)."""
        a, updates = self.ref_upto, 0
        upto = min(upto, a + max(per_branch, 1))
        if upto <= a:
            return 0
        cut = min(max(self.start, a), upto)
        if cut > a:  # before the start: the association's poses, the same for every branch
            beams = rec.beams(a, cut)
            if self.shared:  # counted as the separate maps were
                updates += len(self.branches) * model.integrate(self.branches[0].ref, beams,
                                                                memo="off")  # fmt: skip
            else:
                for b in self.branches:
                    updates += model.integrate(b.ref, beams, memo="off")
        if upto > cut:
            if self.shared:  # the branches part: each its own copy from now on
                for b in self.branches[1:]:
                    b.ref = b.ref.copy()
                self.shared = False
            own = [np.array(b.poses[cut - self.start : upto - self.start]) for b in self.branches]
            updates += model.integrate_each([b.ref for b in self.branches],
                                            rec.beams_each(cut, upto, own))  # fmt: skip
        self.ref_upto = upto
        return updates

    def score(
        self,
        beam_model: BeamModel,
        ref: OccupancyGrid,
        ref_upto: int,
        estimate: np.ndarray,
        sens: np.ndarray,
        ranges: np.ndarray,
        kinds: np.ndarray,
        travel: float,
    ) -> Adoption | None:
        """Score the scan just taken (its usable beams: sensor poses ``sens`` in the robot
        frame, ``ranges``, ``kinds``) if it is due and the branches' maps hold the scans
        before ``ref_upto`` as the association's ``ref`` does: every branch against its
        own reference map, the null (``estimate`` in ``ref``) against the association's.
        Returns the branch to adopt, if one passed."""
        cfg = self.cfg
        if travel < self.next_travel or not self.branches or self.ref_upto != ref_upto:
            return None
        self.next_travel = travel + cfg.window_m / self.window_scans
        if len(kinds) == 0:
            return None
        lp0, blind = beam_model.terms(ref, estimate[None, :], sens, ranges, kinds)
        terms = [beam_model.terms(b.ref, b.pose[None, :], sens, ranges, kinds)
                 for b in self.branches]  # fmt: skip
        both = ~blind[0]
        for _, bl in terms:
            both &= ~bl[0]
        if not both.any():
            return None
        self.scans += 1
        self.beams += int(both.sum())
        for b, (lp, _) in zip(self.branches, terms, strict=True):
            x = float(np.sum((lp[0] - lp0[0])[both])) / cfg.temperature
            b.lam = max(b.lam + log_evalue(x), cfg.reject_nats)
        best = max(self.branches, key=lambda b: b.lam)
        if best.lam < self.threshold:
            return None
        return Adoption(best, self.start, best.lam, self.threshold, self.scans, self.beams)
