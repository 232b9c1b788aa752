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
  nearby beams are not independent (:mod:`mapping.scan_records`).
- The posterior is sampled by tempering with Metropolis-Hastings moves, so its mean and
  covariance rest on many samples (:func:`mapping.pose_samples.smc_posterior`); the
  beam model is evaluated on a distance field of the map for speed
  (:class:`mapping.beam_model.FieldBeamModel`).
- The map matched against is the map *without the most recent* ``ref_lag_m`` of data:
  the newest scans were inserted at the drifted pose and would pull every sample back
  to it (kept here, beside the map).
- A correction must earn its place (:mod:`mapping.loop_correction`): enough effective
  samples, the uncorrected pose outside the posterior, a likelihood ratio on the window
  beyond Wilks' threshold, and then a sequential likelihood-ratio test against the
  uncorrected branch on the scans that come after it (held out from the fit). Every
  check is reported as a :class:`msgs.AssociationReport` with its reason.
- Bounded memory and time (:mod:`mapping.reinsertion`): a snapshot of the map is kept
  every ``snapshot_every_m`` of travel over the last ``reinsert_m``; an accepted
  correction is ramped in over the scans since the oldest of them, which are re-inserted
  into it (exact: no "un-inserting" of clamped log-odds), ``reinsert_per_step`` scans
  per step (the old map is used until the rebuilt one has caught up), so no step stalls.
- The heading sigma the scans are inserted with (eq. 6) is the filter's, but after a
  correction only its growth since then is added to the posterior's. The samples spread
  with their own noise plus the growth of the filter's variance
  (:mod:`mapping.pose_samples`).
- The input heading's systematic drift per radian turned (the gyro's scale error, which
  no sensor on the robot reveals) is tested as hypotheses, each with its own map, on
  the scans as they come (:mod:`mapping.heading_drift`); an adopted drift re-aligns the
  poses since the test began and corrects every later step.
- At the end of a run (:meth:`SampleAssociation.finish`) the checks' evidence is solved
  as a pose graph over the whole history (:mod:`mapping.loop_graph`,
  :mod:`mapping.pose_graph`) and the map rebuilt at its poses, kept only if it draws
  the walls in no more occupied cells than the association's own map.

The parameters are :mod:`mapping.association_config`'s. This module keeps the state
(estimate, cloud, maps, snapshots, records, the drift test) and runs the modules above
scan by scan. Every scan goes into the map, ``ref_lag_m`` later into the
reference map (its cells then taken from the first insertion: :mod:`mapping.ir_memo`)
and into each drift hypothesis' map (the four sharing the lattice of the cones:
``IrInverseModel.integrate_each``).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from mapping.association_config import AssociationConfig
from mapping.beam_model import BeamModel, FieldBeamModel, pair_ratio
from mapping.grid import GridConfig, OccupancyGrid
from mapping.heading_drift import Adoption, DriftBank, drifted_step
from mapping.ir_inverse import KIND_SKIP, InverseModelConfig, IrInverseModel, scan_kinds
from mapping.loop_correction import HeldOut, check_loop
from mapping.loop_graph import LoopGraph, graph_map, scan_hits, window_ends
from mapping.pose_samples import spread
from mapping.reinsertion import Rebuild, Snapshot, keep_snapshot, realign
from mapping.scan_records import ScanRecords
from mapping.se2 import compose, relative, wrap
from msgs import AssociationReport, HeadingEstimate, IrScan, Pose2D

Moved = tuple[np.ndarray, np.ndarray | None, np.ndarray | None]
"""(the estimate after a step, the input's step, the step drift-corrected)."""

FIT_MARGIN_M = 10.0
"""A scan is refused this close to the grid's limit: the drift hypotheses' maps take it
at poses up to a few metres from the estimate's."""


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
        # Each scan goes into the map, then into the reference map: the second time its
        # cell updates are taken from the first (mapping.ir_memo; at most 2 M, 24 MB: the
        # scans of ref_lag_m at 10-20 Hz; the drift branches, at other poses, do not use it).
        self.model = IrInverseModel(inverse or InverseModelConfig(), reuse_cells=2_000_000)
        self._grid_config = grid_config
        self.grid = OccupancyGrid(grid_config)
        self._ref = self.grid.copy()
        self._ref_upto = 0
        # (first scan not in it, travel then, the map then): the re-insertion window.
        self._snaps: list[Snapshot] = [(0, 0.0, self.grid.copy())]
        self._rec = ScanRecords(self.mounts)
        self._rng = np.random.default_rng(seed)
        self._particles = np.zeros((self.config.samples, 3))
        self._estimate: np.ndarray | None = None
        self._prev_in: np.ndarray | None = None
        self._prev_var = 0.0
        self._var_base = 0.0  # heading variance after the last correction
        self._var_at = 0.0  # the filter's variance then
        self._travel = 0.0
        self._last_check = 0.0
        self._pending: HeldOut | None = None
        self._sigma = 0.0
        self._rebuild: Rebuild | None = None
        # The input heading's drift per radian turned (learnt), and its test.
        self._drift = 0.0
        self._drift_spacing = self.config.drift_sigma_per_rad
        self._bank: DriftBank | None = None
        # The checks' evidence as a pose graph, solved at finish() (mapping.loop_graph):
        # the dead-reckoned pose, the turn so far, a candidate's loop edge.
        self._graph = LoopGraph(self.config) if self.config.pose_graph else None
        self._step_in = np.zeros(3)  # the input's last step (the first: its pose)
        self._turn = 0.0
        self._pending_edge = None
        self.graph_outcome = ""  # what finish() did with the graph
        self.reports: list[AssociationReport] = []
        self.cell_updates = 0
        self.skipped_readings = 0
        self.refused_scans = 0  # taken where the grid may not grow (max_cells)
        self.reinserted_scans = 0
        self._beam_model = BeamModel(self.config)
        self._field = FieldBeamModel(self.config)

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
    def drift_per_rad(self) -> float:
        """The input heading's drift per radian turned, as adopted (0 until a test passes)."""
        return self._drift

    @property
    def trajectory(self) -> np.ndarray:
        """(N, 3) corrected poses of every scan so far."""
        return np.array(self._rec.poses) if self._rec.poses else np.zeros((0, 3))

    def outcome_counts(self) -> dict[str, int]:
        out: dict[str, int] = {"accepted": 0, "drift": 0, "unconfirmed": 0, "confirmed": 0,
                               "weak": 0, "worse": 0}  # fmt: skip
        for r in self.reports:
            out[r.outcome] = out.get(r.outcome, 0) + 1
        return out

    def step(self, heading: HeadingEstimate, scan: IrScan) -> AssociationReport | None:
        """Advance by one heading estimate + scan; returns a report if a check decided."""
        cfg = self.config
        p_in = np.array([heading.pose.x, heading.pose.y, heading.pose.theta], dtype=float)
        if not np.all(np.isfinite(p_in)):
            self.skipped_readings += len(scan.status)
            return None
        var = heading.variance_rad2 if math.isfinite(heading.variance_rad2) else self._prev_var
        ranges, kinds = scan_kinds(scan)
        if len(kinds) != len(self.mounts):
            raise ValueError(
                f"IR scan has {len(kinds)} channels but {len(self.mounts)} mounts are "
                "configured: give one (x, y, yaw) mount per channel"
            )
        moved = self._moved(p_in)
        box = self.model.scan_box(moved[0], self.mounts, self.grid.resolution, FIT_MARGIN_M)
        if not self.grid.fits(*box):
            # Beyond the grid's max_cells: refused before anything changes (a record the
            # maps could not take would stop every later insertion). The next scan taken
            # moves the estimate over the whole span, as after the motion filter's gaps.
            self.refused_scans += 1
            return None
        self._move(p_in, var, moved)
        self.skipped_readings += int((kinds == KIND_SKIP).sum())
        sigma = math.sqrt(max(self._var_base + max(var - self._var_at, 0.0), 0.0))
        self._sigma = sigma
        if 3.0 * sigma >= cfg.lost_heading_rad:
            self._bank = None  # a heading that is lost has more than a drift wrong with it
        elif self._bank is None and self._rebuild is None and self._drift_spacing > 0:
            self._bank = DriftBank(cfg, self._drift, self._drift_spacing, len(self._rec),
                                   self._estimate, self._ref, self._ref_upto,
                                   mounts=len(self.mounts))  # fmt: skip
        self._insert(ranges, kinds, sigma, heading.stamp_ns)
        r = self._rec
        r.add_node_if_due(self._travel, cfg.node_spacing_m)
        if self._rebuild is not None:
            self._advance_rebuild()
            return None
        if self._bank is not None:
            keep = kinds != KIND_SKIP
            won = self._bank.score(self._beam_model, self._ref, self._ref_upto, self._estimate,
                                   self.mounts[keep], ranges[keep], kinds[keep], self._travel)  # fmt: skip
            if won is not None:
                return self._adopt(won, heading.stamp_ns)
        if self._pending is not None:
            return self._held_out(ranges, kinds, var, heading.stamp_ns)
        if self._travel - self._last_check < cfg.check_every_m:
            return None
        self._last_check = self._travel
        node = r.covered_node(self._particles, self._estimate, self._travel, cfg)
        if node is None:
            return None
        return self._associate(node, heading.stamp_ns)

    def finish(self) -> OccupancyGrid:
        """The final map. With ``pose_graph``, the graph of the checks' evidence is
        solved (:mod:`mapping.loop_graph`), every scan re-posed from it and the map
        rebuilt at those poses (once, a bounded batch of scans at a time). The rebuilt
        map is taken only if it draws its walls in no more occupied cells than the map
        it replaces (the same scans at poses that agree put each wall in fewer cells;
        passes that disagree double it): otherwise the association's poses and map
        stay, and :attr:`graph_outcome` says why."""
        r = self._rec
        self.graph_outcome, new, grid, updates = graph_map(
            self._graph, r, self.grid, self.model, self._grid_config
        )
        self.cell_updates += updates
        if new is None or grid is None:
            return self.grid
        for i in range(len(r)):
            r.poses[i] = new[i]
        self.reinserted_scans += len(r)
        self.grid, self._ref, self._ref_upto, self._rebuild = grid, grid, len(r), None
        self._estimate = new[-1].copy()
        self._pending = self._bank = None
        return self.grid

    def log_likelihood(
        self, poses: np.ndarray, sens: np.ndarray, ranges: np.ndarray, kinds: np.ndarray
    ) -> np.ndarray:
        """Eq. 7-8 (:class:`mapping.beam_model.BeamModel`, ray casting) for each pose
        (P, 3) in the reference map: the map without the most recent ``ref_lag_m``."""
        return self._beam_model.log_likelihood(self._ref, poses, sens, ranges, kinds)

    # -- internals -------------------------------------------------------------------------
    def _moved(self, p_in: np.ndarray) -> Moved:
        """Where the step to ``p_in`` puts the estimate, with the input's step and the
        step drift-corrected (None, None for the first); nothing changes."""
        if self._estimate is None or self._prev_in is None:
            return p_in, None, None
        rel_in = relative(self._prev_in, p_in)
        rel = drifted_step(rel_in, self._drift)
        return compose(self._estimate, rel), rel_in, rel

    def _move(self, p_in: np.ndarray, var: float, moved: Moved) -> None:
        """Dead-reckon the estimate to ``moved`` (:meth:`_moved` of ``p_in``) and spread
        the cloud by the step."""
        estimate, rel_in, rel = moved
        if rel_in is None or rel is None:
            self._estimate = p_in.copy()
            self._step_in = p_in.copy()
            self._particles = np.tile(p_in, (self.config.samples, 1))
        else:
            if self._bank is not None:
                self._bank.move(rel_in)
            d = float(math.hypot(rel[0], rel[1]))
            self._travel += d
            self._estimate = estimate
            self._step_in = rel_in
            self._turn += abs(float(rel[2]))
            dvar = max(0.0, var - self._prev_var)
            self._particles = spread(self._particles, rel, d, dvar, self.config, self._rng)
        self._prev_in, self._prev_var = p_in, var

    def _insert(self, ranges: np.ndarray, kinds: np.ndarray, sigma: float, stamp_ns: int) -> None:
        """Record the scan at the estimate, insert it into the map, age the records older
        than ``ref_lag_m`` of travel into the reference map, keep the snapshots."""
        r = self._rec
        cfg = self.config
        n = len(r)
        if self._rebuild is None:
            keep_snapshot(self._snaps, n, self._travel, self.grid, cfg)
        r.append(self._estimate.copy(), sigma, ranges, kinds, self._travel, stamp_ns)
        if self._graph is not None:
            self._graph.record(self._step_in, self._drift, self._travel, self._turn,
                               self._prev_var, scan_hits(self.mounts, ranges, kinds))  # fmt: skip
        if self._bank is not None:
            self._bank.record()
        self.cell_updates += self.model.integrate(self.grid, r.beams(n, n + 1), "keep")
        upto = r.older_than(self._ref_upto, self._travel - cfg.ref_lag_m)
        # At most reinsert_per_step scans a step (after turning on the spot many scans
        # come of age at once; the reference map may lag a few steps more).
        upto = min(upto, self._ref_upto + cfg.reinsert_per_step)
        aged = upto - self._ref_upto
        if upto > self._ref_upto:
            self.cell_updates += self.model.integrate(self._ref, r.beams(self._ref_upto, upto),
                                                      "take")  # fmt: skip
            self._ref_upto = upto
        if self._bank is not None:
            # The branches take what is left of the step's budget (at least one scan each).
            k = len(self._bank.branches)
            budget = max(cfg.reinsert_per_step - aged, k) // max(k, 1)
            self.cell_updates += self._bank.age(r, self._ref_upto, self.model, budget)

    def _pair(self, sens: np.ndarray, ranges: np.ndarray, kinds: np.ndarray):
        """(pose a, pose b) -> the beams' likelihood ratio of a over b in the reference
        map (ray casting, eq. 7-8), on the beams both see mapped space with."""
        t = self.config.temperature

        def pair(a: np.ndarray, b: np.ndarray) -> tuple[float, int]:
            terms = self._beam_model.terms(self._ref, np.stack([a, b]), sens, ranges, kinds)
            return pair_ratio(terms, t)

        return pair

    def _associate(self, node: int, stamp_ns: int) -> AssociationReport | None:
        cfg = self.config
        if 3.0 * self._sigma >= cfg.lost_heading_rad:
            # The heading is lost (the filter says so): the samples point everywhere, any
            # wall matches somewhere; no correction can be trusted.
            why = (f"heading lost: 3 sigma {math.degrees(3 * self._sigma):.0f} deg >= "
                   f"{math.degrees(cfg.lost_heading_rad):.0f} deg since the last correction")  # fmt: skip
            rep = AssociationReport(stamp_ns, "weak", node, cfg.samples, 1.0, 0.0, reason=why)
            self.reports.append(rep)
            return rep
        window = self._rec.window(self._estimate, self._travel, cfg)
        p = self._particles
        reach = cfg.max_range_m + 1.0
        self._field.set_map(self._ref, (p[:, 0].min() - reach, p[:, 1].min() - reach,
                                        p[:, 0].max() + reach, p[:, 1].max() + reach))  # fmt: skip
        check = check_loop(cfg, p, self._estimate, window, self._field.log_likelihood,
                           self._rng, node, stamp_ns, self._pair(*window))  # fmt: skip
        post = check.posterior
        edge = None
        if self._graph is not None and post is not None:
            edge = self._graph.loop_edge(len(self._rec) - 1, post.mean, post.cov,
                                         self._rec.poses, window_ends(post.mean, *window))  # fmt: skip
        if check.report.outcome == "confirmed" and post is not None:
            # The evidence agrees with the estimate: the cloud becomes the posterior (the
            # information is kept; the estimate is not moved).
            self._particles = post.samples.copy()
            if self._graph is not None:
                self._graph.add_loop(edge)
        if check.report.outcome != "candidate":
            self.reports.append(check.report)
            return check.report
        self._pending = HeldOut(check, self._estimate.copy(), self._travel)
        self._pending_edge = edge  # a loop edge once the held-out test accepts it
        return None

    def _held_out(
        self, ranges: np.ndarray, kinds: np.ndarray, var: float, stamp_ns: int
    ) -> AssociationReport | None:
        """Score the new scan on both branches; decide the pending candidate when due."""
        h = self._pending
        assert h is not None and h.check.posterior is not None
        cfg = self.config
        keep = kinds != KIND_SKIP
        if keep.any():
            h.score(self._estimate, self._pair(self.mounts[keep], ranges[keep], kinds[keep]))
        decision = h.decision(self._travel, cfg)
        if decision is None:
            return None
        self._pending = None
        rep = h.check.report
        why = (f"held-out LR {h.lam:.1f} nats over {h.scans} later scans ({h.beams} beams "
               "seeing mapped space from both branches) "
               f"({cfg.reject_nats} .. {cfg.confirm_nats}); {rep.reason.removeprefix('candidate: ')}")  # fmt: skip
        if decision == "unconfirmed":
            report = replace(rep, stamp_ns=stamp_ns, outcome="unconfirmed",
                             reason=f"not confirmed by later data: {why}")  # fmt: skip
            self.reports.append(report)
            return report
        if self._graph is not None:
            self._graph.add_loop(self._pending_edge)
        corrected = h.corrected(self._estimate)
        moved = relative(h.base, self._estimate)
        post = h.check.posterior
        self._particles = compose(post.samples, np.broadcast_to(moved, post.samples.shape))
        realigned = self._realign(corrected)
        self._var_base, self._var_at = float(post.cov[2, 2]), var
        report = replace(rep, stamp_ns=stamp_ns, outcome="accepted", realigned_scans=realigned,
                         reason=f"accepted: {why}")  # fmt: skip
        self.reports.append(report)
        return report

    def _realign(self, corrected: np.ndarray) -> int:
        """Re-align the scans since the oldest snapshot kept (about ``reinsert_m`` back)
        so the last pose is ``corrected``, and start rebuilding the reference map and the
        map from that snapshot (:mod:`mapping.reinsertion`). Returns the scans moved."""
        self._rebuild, self._snaps, moved = realign(self._rec, self._snaps, self._travel,
                                                    corrected, self.config)  # fmt: skip
        self._estimate = np.array(corrected, dtype=float)
        self._bank = None  # its null was the uncorrected branch: restarted after the rebuild
        self.reinserted_scans += moved
        self._advance_rebuild()
        return moved

    def _adopt(self, won: Adoption, stamp_ns: int) -> AssociationReport:
        """Take the drift branch that passed (:mod:`mapping.heading_drift`): its poses
        since the bank's start, its reference map and its pose; dead-reckon with its drift
        from now on; rebuild the map from its reference map (a few scans per step)."""
        b, n, upto = won.branch, len(self._rec), self._ref_upto
        old, prev = self._estimate.copy(), self._drift
        before = [p.copy() for p in self._rec.poses] if self._graph is not None else []
        self._particles, self._snaps = won.rebase(self._rec, self._particles, old, self._snaps,
                                                  upto, self._travel)  # fmt: skip
        self._estimate, self._drift = b.pose.copy(), b.drift
        if self._graph is not None:
            self._graph.adopt(won.start, b.drift)
            self._graph.rebase(before, self._rec.poses)
        self._drift_spacing = won.next_spacing(self._drift_spacing, self.config.drift_steps)
        self._pending, self._bank = None, None
        self._rebuild = Rebuild(upto, upto, b.ref)
        self.reinserted_scans += n - won.start
        self._advance_rebuild()
        report = won.report(stamp_ns, prev, old, self.config.samples, n)
        self.reports.append(report)
        return report

    def _advance_rebuild(self) -> None:
        """Re-insert up to ``reinsert_per_step`` scans into the maps being rebuilt; once
        they have caught up, they replace the map and the reference map."""
        b = self._rebuild
        assert b is not None
        cfg = self.config
        self.cell_updates += b.advance(self._rec, self.model, self._travel - cfg.ref_lag_m,
                                       cfg.reinsert_per_step)  # fmt: skip
        if b.done(self._rec):
            assert b.grid is not None
            self._ref, self._ref_upto, self.grid = b.ref, b.ref_upto, b.grid
            self._rebuild = None
