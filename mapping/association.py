"""Sample-based data association for IR grid mapping (ir-grid-mapping.txt §4, eq. 7-8).

Six IR beams are too sparse for scan matching, so the paper represents the robot's pose
by samples (particles) that spread as the robot moves (fig. 9), drops a node every 2 m
(fig. 11 b), and when the sample cloud covers an earlier node (fig. 11 c) weights every
sample with the beam model against the map built so far,

    p(z | x, m) = prod_k p(z^k | x, m)                                         (7)
    p(z^k | x, m) = a_hit p_hit + a_rand p_rand + a_max p_max                 (8)

(p_hit a Gaussian about the range expected by ray casting the map from the sample, p_rand
uniform over [0, z_max], p_max the point mass of a reading that saw nothing). The
weighted mean corrects the pose (fig. 11 d), the samples are resampled, and the range
data taken since the last correction are re-aligned and re-inserted (fig. 11 e, 12).

Choices made here where the paper is silent, and beyond the paper (each explained in the
module that holds it):

- The window: the samples are weighted with the scans of the last ``window_m`` of travel
  (short-term odometry is good), the log-likelihood tempered by ``temperature`` because
  nearby beams are not independent, and annealed over ``refine_rounds`` of weighting,
  resampling and a shrinking jitter (:mod:`mapping.scan_records`,
  :mod:`mapping.pose_samples`).
- The map matched against is the map *without the most recent* ``ref_lag_m`` of data:
  the newest scans were inserted at the drifted pose and would pull every sample back
  to it (kept here, beside the map).
- Re-alignment ramps the correction in over the span since the last correction
  (:mod:`mapping.loop_correction`); the span is re-inserted into a snapshot of the map
  taken at the last correction (exact: no "un-inserting" of clamped log-odds; here).
- Never make the map worse: the uncorrected branch is kept when the evidence is flat
  ("weak"), when the uncorrected pose is plausible under the posterior ("confirmed"), or
  when the corrected pose does not explain the window better ("worse"); every check is
  reported as a :class:`msgs.AssociationReport` with its reason
  (:mod:`mapping.loop_correction`).
- Beam model against a map: the expected range is the centre of the first run of
  occupied cells along the ray, and sigma_hit covers the map's wall thickness as well as
  the sensor's noise; both were needed for an undrifted run to stay untouched
  (:mod:`mapping.beam_model`).
- The samples spread with their own noise model plus the growth of the heading filter's
  variance, which is overconfident over tens of metres (:mod:`mapping.pose_samples`).

Modules: :mod:`mapping.association_config` (the parameters), :mod:`mapping.scan_records`
(the scans, the nodes and the window), :mod:`mapping.pose_samples` (the sample cloud:
spread, weights, resampling, annealing), :mod:`mapping.beam_model` (eq. 7-8 against the
map), :mod:`mapping.loop_correction` (the acceptance tests and the re-alignment),
:mod:`mapping.se2` (pose algebra). This module keeps the state (estimate, cloud, maps,
records) and runs them scan by scan.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from mapping.association_config import AssociationConfig
from mapping.beam_model import BeamModel
from mapping.grid import GridConfig, OccupancyGrid
from mapping.ir_inverse import KIND_SKIP, InverseModelConfig, IrInverseModel, scan_kinds
from mapping.loop_correction import check_loop, realigned_poses
from mapping.pose_samples import spread
from mapping.scan_records import ScanRecords
from mapping.se2 import compose, relative, wrap
from msgs import AssociationReport, HeadingEstimate, IrScan, Pose2D


class SampleAssociation:
    """Builds an IR occupancy grid while correcting the pose by sample-based association.

    Feed :meth:`step` with the heading filter's estimate (its ``pose`` is the
    encoder-position + fused-heading pose) and the IR scan taken there. ``grid`` is the
    map (with corrections), ``pose`` the corrected pose, ``reports`` what every check did.
    """

    def __init__(
        self,
        mounts: np.ndarray,
        config: AssociationConfig | None = None,
        grid_config: GridConfig | None = None,
        inverse: InverseModelConfig | None = None,
        seed: int = 0,
    ) -> None:
        self.mounts = np.atleast_2d(np.asarray(mounts, dtype=float))
        if self.mounts.ndim != 2 or self.mounts.shape[1] != 3:
            raise ValueError("IR mounts must be (K, 3): x, y, yaw of each sensor on the robot")
        self.config = config or AssociationConfig()
        self.model = IrInverseModel(inverse or InverseModelConfig())
        self.grid = OccupancyGrid(grid_config)
        self._anchor = self.grid.copy()
        self._ref = self.grid.copy()
        self._anchor_idx = 0
        self._ref_upto = 0
        self._rec = ScanRecords(self.mounts)
        self._rng = np.random.default_rng(seed)
        self._particles = np.zeros((self.config.samples, 3))
        self._estimate: np.ndarray | None = None
        self._prev_in: np.ndarray | None = None
        self._prev_var = 0.0
        self._travel = 0.0
        self._last_check = 0.0
        self.reports: list[AssociationReport] = []
        self.cell_updates = 0
        self.skipped_readings = 0
        self._beam_model = BeamModel(self.config)

    # -- public ---------------------------------------------------------------------------
    @property
    def pose(self) -> Pose2D:
        e = self._estimate if self._estimate is not None else np.zeros(3)
        return Pose2D(float(e[0]), float(e[1]), float(wrap(e[2])))

    @property
    def particles(self) -> np.ndarray:
        return self._particles.copy()

    @property
    def nodes(self) -> list[Pose2D]:
        return [Pose2D(*map(float, self._rec.poses[i])) for i in self._rec.nodes]

    @property
    def trajectory(self) -> np.ndarray:
        """(N, 3) corrected poses of every scan so far."""
        return np.array(self._rec.poses) if self._rec.poses else np.zeros((0, 3))

    def outcome_counts(self) -> dict[str, int]:
        out: dict[str, int] = {"accepted": 0, "confirmed": 0, "weak": 0, "worse": 0}
        for r in self.reports:
            out[r.outcome] = out.get(r.outcome, 0) + 1
        return out

    def step(self, heading: HeadingEstimate, scan: IrScan) -> AssociationReport | None:
        """Advance by one heading estimate + scan; returns a report if a check ran."""
        cfg = self.config
        p_in = np.array([heading.pose.x, heading.pose.y, heading.pose.theta], dtype=float)
        if not np.all(np.isfinite(p_in)):
            self.skipped_readings += len(scan.status)
            return None
        var = heading.variance_rad2 if math.isfinite(heading.variance_rad2) else self._prev_var
        self._move(p_in, var)
        ranges, kinds = scan_kinds(scan)
        if len(kinds) != len(self.mounts):
            raise ValueError(
                f"IR scan has {len(kinds)} channels but {len(self.mounts)} mounts are "
                "configured: give one (x, y, yaw) mount per channel"
            )
        self.skipped_readings += int((kinds == KIND_SKIP).sum())
        self._insert(ranges, kinds, math.sqrt(max(var, 0.0)), heading.stamp_ns)
        r = self._rec
        r.add_node_if_due(self._travel, cfg.node_spacing_m)
        if self._travel - self._last_check < cfg.check_every_m:
            return None
        self._last_check = self._travel
        node = r.covered_node(self._particles, self._estimate, self._travel, cfg)
        if node is None:
            return None
        report = self._associate(node, heading.stamp_ns)
        self.reports.append(report)
        return report

    def finish(self) -> OccupancyGrid:
        """The final map (kept for symmetry with a streaming service's shutdown)."""
        return self.grid

    def log_likelihood(
        self, poses: np.ndarray, sens: np.ndarray, ranges: np.ndarray, kinds: np.ndarray
    ) -> np.ndarray:
        """Eq. 7-8 (:class:`mapping.beam_model.BeamModel`) for each pose (P, 3) in the
        reference map: the map without the most recent ``ref_lag_m`` of data."""
        return self._beam_model.log_likelihood(self._ref, poses, sens, ranges, kinds)

    # -- internals -------------------------------------------------------------------------
    def _move(self, p_in: np.ndarray, var: float) -> None:
        """Dead-reckon the estimate and spread the cloud by the step to ``p_in``."""
        if self._estimate is None:
            self._estimate = p_in.copy()
            self._particles = np.tile(p_in, (self.config.samples, 1))
        else:
            rel = relative(self._prev_in, p_in)
            d = float(math.hypot(rel[0], rel[1]))
            self._travel += d
            self._estimate = compose(self._estimate, rel)
            dvar = max(0.0, var - self._prev_var)
            self._particles = spread(self._particles, rel, d, dvar, self.config, self._rng)
        self._prev_in, self._prev_var = p_in, var

    def _insert(self, ranges: np.ndarray, kinds: np.ndarray, sigma: float, stamp_ns: int) -> None:
        """Record the scan at the estimate, insert it into the map, and age the records
        older than ``ref_lag_m`` of travel into the reference map."""
        r = self._rec
        r.append(self._estimate.copy(), sigma, ranges, kinds, self._travel, stamp_ns)
        n = len(r)
        self.cell_updates += self.model.integrate(self.grid, r.beams(n - 1, n))
        upto = r.older_than(self._ref_upto, self._travel - self.config.ref_lag_m)
        if upto > self._ref_upto:
            self.cell_updates += self.model.integrate(self._ref, r.beams(self._ref_upto, upto))
            self._ref_upto = upto

    def _associate(self, node: int, stamp_ns: int) -> AssociationReport:
        window = self._rec.window(self._estimate, self._travel, self.config)
        check = check_loop(
            self.config, self._particles, self._estimate, window, self.log_likelihood,
            self._rng, node, stamp_ns,
        )  # fmt: skip
        if check.corrected is None or check.particles is None:
            return check.report
        realigned = self._realign(check.corrected)
        self._particles = check.particles
        return replace(check.report, realigned_scans=realigned)

    def _realign(self, corrected: np.ndarray) -> int:
        """Re-align the records since the last correction so the last pose is ``corrected``;
        rebuild the map from the snapshot taken then (exact: no "un-inserting" of clamped
        log-odds). Returns the number of scans moved."""
        r = self._rec
        a, n = self._anchor_idx, len(r)
        new = realigned_poses(np.array(r.poses[a:n]), np.array(r.travel[a:n]), corrected)
        for i in range(a, n):
            r.poses[i] = new[i - a]
        grid = self._anchor.copy()
        self.cell_updates += self.model.integrate(grid, r.beams(a, n))
        self.grid = grid
        self._anchor = grid.copy()
        self._ref = grid.copy()
        self._anchor_idx = n
        self._ref_upto = n
        self._estimate = np.array(corrected, dtype=float)
        return n - a
