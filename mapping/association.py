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

Choices made here where the paper is silent, and beyond the paper:

- The samples are weighted with the scans of the last ``window_m`` of travel (short-term
  odometry is good), with the log-likelihood tempered by ``temperature`` because nearby
  beams are not independent. Weighting, resampling and a shrinking jitter are repeated
  ``refine_rounds`` times (annealing), which sharpens the estimate from few samples.
- The map matched against is the map *without the most recent* ``ref_lag_m`` of data:
  the newest scans were inserted at the drifted pose and would pull every sample back
  to it.
- Re-alignment: the heading correction is ramped in over the span since the last
  correction (proportional to the distance travelled), the positions re-integrated from
  the recorded steps, and the remaining position gap ramped in the same way, so the pose
  at the start of the span is unchanged and the last one equals the corrected pose. The
  span is re-inserted into a snapshot of the map taken at the last correction (exact:
  no "un-inserting" of clamped log-odds).
- Never make the map worse: the uncorrected branch is kept when the evidence is flat
  (effective sample size over sample count above ``ess_max``: outcome "weak"), when the
  uncorrected pose is plausible under the importance-weighted posterior of the prior
  cloud (squared Mahalanobis distance below ``significance_d2``, 11.34 = chi-square 3 dof
  at 99 %: outcome "confirmed"; the annealed estimate alone would overfit the noise and
  move an undrifted pose), or when the corrected pose does not explain the window better
  than the uncorrected one by ``lr_min`` nats (tempered log-likelihood ratio: outcome
  "worse"). Every check is reported as a :class:`msgs.AssociationReport` with its reason.
- Beam model against a map: the expected range z* is the centre of the first run of
  occupied cells along the ray (eq. 6 widens walls towards the robot, so the first
  occupied cell is biased short), and sigma_hit (0.2 m) covers the map's wall thickness
  as well as the sensor's noise. Both were needed for an undrifted run to stay untouched.
- The samples spread with their own noise model (``heading_noise_*``,
  ``position_noise_*``) plus the growth of the heading filter's variance: the heading
  filter of eq. 1-4 treats the gyro's scale error as white and is overconfident over
  tens of metres, and the cloud must cover the real error to find the node.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from mapping.grid import GridConfig, OccupancyGrid, logit
from mapping.ir_inverse import (
    KIND_CLEAR,
    KIND_HIT,
    KIND_SKIP,
    Beams,
    InverseModelConfig,
    IrInverseModel,
    scan_kinds,
)
from msgs import AssociationReport, HeadingEstimate, IrScan, Pose2D
from numerics.angles import wrap, wrap_angles


@dataclass(frozen=True)
class AssociationConfig:
    """Parameters of sample-based data association (defaults: the simulated Pioneer)."""

    samples: int = 200
    node_spacing_m: float = 2.0
    min_loop_m: float = 8.0
    cover_radius_m: float = 1.0
    check_every_m: float = 0.5
    window_m: float = 1.5
    window_scans: int = 8
    ref_lag_m: float = 3.0
    heading_noise_rad_per_sqrt_m: float = 0.025
    heading_noise_per_sqrt_rad: float = 0.03
    position_noise_m_per_sqrt_m: float = 0.02
    a_hit: float = 0.75
    a_rand: float = 0.2
    a_max: float = 0.05
    sigma_hit_m: float = 0.2
    sigma_hit_per_m2: float = 0.01
    occupied_p: float = 0.65
    temperature: float = 4.0
    refine_rounds: int = 3
    ess_max: float = 0.5
    lr_min: float = 2.0
    significance_d2: float = 11.34
    max_range_m: float = 5.5

    def __post_init__(self) -> None:
        if self.samples < 10:
            raise ValueError("association samples must be >= 10")
        for name in ("node_spacing_m", "check_every_m", "window_m", "temperature"):
            if getattr(self, name) <= 0:
                raise ValueError(f"association {name} must be > 0")
        if self.min_loop_m < self.ref_lag_m:
            raise ValueError(
                "association min_loop_m must be >= ref_lag_m (a node must lie in the "
                "map matched against)"
            )
        if abs(self.a_hit + self.a_rand + self.a_max - 1.0) > 1e-6:
            raise ValueError("association a_hit + a_rand + a_max must be 1 (eq. 8 weights)")


def _compose(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Pose composition a (+) b on (..., 3) arrays."""
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    return np.stack(
        [
            a[..., 0] + c * b[..., 0] - s * b[..., 1],
            a[..., 1] + s * b[..., 0] + c * b[..., 1],
            a[..., 2] + b[..., 2],
        ],
        axis=-1,
    )


def _relative(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(-a) (+) b: pose b in the frame of pose a."""
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    dx, dy = b[..., 0] - a[..., 0], b[..., 1] - a[..., 1]
    dth = wrap_angles(b[..., 2] - a[..., 2])
    return np.stack([c * dx + s * dy, -s * dx + c * dy, dth], axis=-1)


def _systematic(weights: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    n = len(weights)
    pos = (rng.random() + np.arange(n)) / n
    return np.minimum(np.searchsorted(np.cumsum(weights), pos), n - 1)


@dataclass
class _Records:
    poses: list[np.ndarray] = field(default_factory=list)
    sigma: list[float] = field(default_factory=list)
    ranges: list[np.ndarray] = field(default_factory=list)
    kinds: list[np.ndarray] = field(default_factory=list)
    travel: list[float] = field(default_factory=list)
    stamps: list[int] = field(default_factory=list)


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
        self._rec = _Records()
        self._nodes: list[int] = []
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
        self._l_occ = logit(self.config.occupied_p)

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
        return [Pose2D(*map(float, self._rec.poses[i])) for i in self._nodes]

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
        if self._estimate is None:
            self._estimate = p_in.copy()
            self._particles = np.tile(p_in, (cfg.samples, 1))
        else:
            rel = _relative(self._prev_in, p_in)
            d = float(math.hypot(rel[0], rel[1]))
            self._travel += d
            self._estimate = _compose(self._estimate, rel)
            self._spread(rel, d, max(0.0, var - self._prev_var))
        self._prev_in, self._prev_var = p_in, var
        ranges, kinds = scan_kinds(scan)
        if len(kinds) != len(self.mounts):
            raise ValueError(
                f"IR scan has {len(kinds)} channels but {len(self.mounts)} mounts are "
                "configured: give one (x, y, yaw) mount per channel"
            )
        self.skipped_readings += int((kinds == KIND_SKIP).sum())
        r = self._rec
        r.poses.append(self._estimate.copy())
        r.sigma.append(math.sqrt(max(var, 0.0)))
        r.ranges.append(ranges)
        r.kinds.append(kinds)
        r.travel.append(self._travel)
        r.stamps.append(heading.stamp_ns)
        n = len(r.poses)
        self.cell_updates += self.model.integrate(self.grid, self._beams(n - 1, n))
        # Age records into the reference map.
        upto = self._ref_upto
        while upto < n and r.travel[upto] < self._travel - cfg.ref_lag_m:
            upto += 1
        if upto > self._ref_upto:
            self.cell_updates += self.model.integrate(self._ref, self._beams(self._ref_upto, upto))
            self._ref_upto = upto
        if not self._nodes or self._travel - r.travel[self._nodes[-1]] >= cfg.node_spacing_m:
            self._nodes.append(n - 1)
        if self._travel - self._last_check < cfg.check_every_m:
            return None
        self._last_check = self._travel
        node = self._covered_node()
        if node is None:
            return None
        report = self._associate(node, heading.stamp_ns)
        self.reports.append(report)
        return report

    def finish(self) -> OccupancyGrid:
        """The final map (kept for symmetry with a streaming service's shutdown)."""
        return self.grid

    # -- internals -------------------------------------------------------------------------
    def _beams(self, start: int, stop: int) -> Beams:
        r = self._rec
        if stop <= start:
            return Beams.concat([])
        poses = np.array(r.poses[start:stop])
        kinds = np.concatenate(r.kinds[start:stop])
        ranges = np.concatenate(r.ranges[start:stop])
        k = len(self.mounts)
        sens = _compose(np.repeat(poses, k, axis=0), np.tile(self.mounts, (stop - start, 1)))
        sig = np.repeat(np.array(r.sigma[start:stop]), k)
        keep = kinds != KIND_SKIP
        return Beams(
            sens[keep, 0],
            sens[keep, 1],
            sens[keep, 2],
            np.where(kinds == KIND_HIT, ranges, np.nan)[keep],
            kinds[keep],
            sig[keep],
        )

    def _spread(self, rel: np.ndarray, d: float, dvar: float) -> None:
        cfg = self.config
        n = len(self._particles)
        sth = math.sqrt(
            cfg.heading_noise_rad_per_sqrt_m**2 * d
            + cfg.heading_noise_per_sqrt_rad**2 * abs(rel[2])
            + dvar
        )
        spos = cfg.position_noise_m_per_sqrt_m * math.sqrt(d)
        noisy = np.empty((n, 3))
        noisy[:, 0] = rel[0] + self._rng.normal(0.0, spos, n)
        noisy[:, 1] = rel[1] + self._rng.normal(0.0, spos, n)
        noisy[:, 2] = rel[2] + self._rng.normal(0.0, sth, n)
        self._particles = _compose(self._particles, noisy)

    def _covered_node(self) -> int | None:
        cfg = self.config
        r = self._rec
        best, best_d = None, math.inf
        for idx in self._nodes:
            if r.travel[idx] > self._travel - cfg.min_loop_m:
                break
            node = r.poses[idx]
            d = np.hypot(self._particles[:, 0] - node[0], self._particles[:, 1] - node[1])
            if d.min() <= cfg.cover_radius_m:
                dist = float(math.hypot(node[0] - self._estimate[0], node[1] - self._estimate[1]))
                if dist < best_d:
                    best, best_d = idx, dist
        return best

    def _window(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Sensor poses in the current robot frame, ranges and kinds of the window's beams."""
        cfg = self.config
        r = self._rec
        n = len(r.poses)
        first = n - 1
        while first > 0 and r.travel[first - 1] >= self._travel - cfg.window_m:
            first -= 1
        idx = np.unique(np.linspace(first, n - 1, min(cfg.window_scans, n - first)).round())
        idx = idx.astype(int)
        poses = np.array([r.poses[i] for i in idx])
        rel = _relative(self._estimate[None, :], poses)
        k = len(self.mounts)
        sens = _compose(np.repeat(rel, k, axis=0), np.tile(self.mounts, (len(idx), 1)))
        ranges = np.concatenate([r.ranges[i] for i in idx])
        kinds = np.concatenate([r.kinds[i] for i in idx])
        keep = kinds != KIND_SKIP
        return sens[keep], ranges[keep], kinds[keep]

    def log_likelihood(
        self, poses: np.ndarray, sens: np.ndarray, ranges: np.ndarray, kinds: np.ndarray
    ) -> np.ndarray:
        """Eq. 7-8: sum over beams of log p(z^k | x, m) for each pose (P, 3); ray casting
        in the reference map (cells with p > occupied_p are obstacles, others free)."""
        cfg = self.config
        g = self._ref
        res = g.resolution
        world = _compose(poses[:, None, :], sens[None, :, :])  # (P, M, 3)
        z_max = cfg.max_range_m
        t = np.arange(0.5 * res, z_max + 3 * cfg.sigma_hit_m, res)
        ox, oy = world[..., 0][..., None], world[..., 1][..., None]
        c, s = np.cos(world[..., 2])[..., None], np.sin(world[..., 2])[..., None]
        row, col = g.cell_of(ox + c * t, oy + s * t)  # (P, M, T)
        inside = g.inside(row, col)
        rows, cols = g.shape
        occ = (g.logodds > self._l_occ).reshape(-1)
        flat = np.where(inside, row * cols + col, 0)
        hit = inside & occ[flat]
        any_hit = hit.any(axis=-1)
        # The expected range is the centre of the first run of occupied cells: eq. 6 widens
        # walls towards the robot, and the first occupied cell would be biased short.
        first = np.argmax(hit, axis=-1)
        started = np.arange(len(t)) >= first[..., None]
        run = started & (np.cumsum(started & ~hit, axis=-1) == 0)
        first = first + (run.sum(axis=-1) - 1) // 2
        z_star = np.where(any_hit, t[first], np.inf)  # (P, M)
        z = np.broadcast_to(ranges[None, :], z_star.shape)
        sig = np.hypot(cfg.sigma_hit_m, cfg.sigma_hit_per_m2 * np.nan_to_num(z, nan=z_max) ** 2)
        with np.errstate(invalid="ignore", over="ignore"):
            p_hit = np.where(
                np.isfinite(z_star),
                np.exp(-0.5 * ((z - z_star) / sig) ** 2) / (sig * math.sqrt(2 * math.pi)),
                0.0,
            )
        p_rand = 1.0 / z_max
        clear = (kinds == KIND_CLEAR)[None, :]
        sig_max = math.hypot(cfg.sigma_hit_m, cfg.sigma_hit_per_m2 * z_max**2)
        p_max = (z_star > z_max - sig_max).astype(float)
        p = np.where(
            clear,
            cfg.a_max * p_max + cfg.a_rand * p_rand,
            cfg.a_hit * np.nan_to_num(p_hit) + cfg.a_rand * p_rand,
        )
        return np.log(p).sum(axis=-1)

    def _weights(self, ll: np.ndarray) -> np.ndarray:
        a = ll / self.config.temperature
        w = np.exp(a - a.max())
        return w / w.sum()

    def _associate(self, node: int, stamp_ns: int) -> AssociationReport:
        cfg = self.config
        sens, ranges, kinds = self._window()
        n = len(self._particles)
        if len(kinds) == 0:
            return AssociationReport(stamp_ns, "weak", node, n, 1.0, 0.0, reason="no usable beams")
        prior = self._particles
        w = self._weights(self.log_likelihood(prior, sens, ranges, kinds))
        ess = float(1.0 / np.sum(w**2)) / n
        if ess > cfg.ess_max:
            return AssociationReport(
                stamp_ns, "weak", node, n, ess, 0.0,
                reason=f"evidence too flat (ESS/N {ess:.2f} > {cfg.ess_max})",
            )  # fmt: skip
        est = self._estimate
        mean0, _ = self._mean_std(prior, w)
        d2 = self._mahalanobis2(prior, w, est)
        if d2 < cfg.significance_d2:
            # The uncorrected pose is plausible under the posterior: keep it, and leave the
            # cloud as it was (resampling on biased evidence would drag it away).
            corr = self._correction(mean0, est)
            return AssociationReport(
                stamp_ns, "confirmed", node, n, ess, self._lr(mean0, est, sens, ranges, kinds),
                float(corr[0]), float(corr[1]), float(corr[2]),
                reason=f"uncorrected pose inside the posterior (d2 {d2:.1f} < "
                f"{cfg.significance_d2}): kept",
            )  # fmt: skip
        parts, weights = prior, w
        for _ in range(cfg.refine_rounds):
            _, std = self._mean_std(parts, weights)
            parts = parts[_systematic(weights, self._rng)]
            jit = np.maximum(0.5 * std, [0.01, 0.01, math.radians(0.2)])
            parts = parts + self._rng.normal(0.0, 1.0, parts.shape) * jit
            weights = self._weights(self.log_likelihood(parts, sens, ranges, kinds))
        mean, _ = self._mean_std(parts, weights)
        lr = self._lr(mean, est, sens, ranges, kinds)
        corr = self._correction(mean, est)
        if lr < cfg.lr_min:
            return AssociationReport(
                stamp_ns, "worse", node, n, ess, lr, float(corr[0]), float(corr[1]),
                float(corr[2]),
                reason=f"corrected pose not better by {cfg.lr_min} nats: uncorrected branch kept",
            )  # fmt: skip
        realigned = self._realign(mean)
        self._particles = parts[_systematic(weights, self._rng)]
        return AssociationReport(
            stamp_ns, "accepted", node, n, ess, lr,
            float(corr[0]), float(corr[1]), float(corr[2]), realigned,
        )  # fmt: skip

    def _lr(self, a: np.ndarray, b: np.ndarray, sens, ranges, kinds) -> float:  # noqa: ANN001
        """Tempered log-likelihood ratio of pose a over pose b on the window's beams."""
        ll = self.log_likelihood(np.stack([a, b]), sens, ranges, kinds)
        return float(ll[0] - ll[1]) / self.config.temperature

    @staticmethod
    def _correction(new: np.ndarray, old: np.ndarray) -> np.ndarray:
        return np.array([new[0] - old[0], new[1] - old[1], float(wrap(new[2] - old[2]))])

    @staticmethod
    def _mahalanobis2(parts: np.ndarray, w: np.ndarray, pose: np.ndarray) -> float:
        """Squared Mahalanobis distance of ``pose`` from the weighted samples' mean."""
        mean, _ = SampleAssociation._mean_std(parts, w)
        d = parts - mean
        d[:, 2] = wrap(d[:, 2])
        cov = (w[:, None] * d).T @ d + np.diag([1e-6, 1e-6, 1e-8])
        dev = np.array([pose[0] - mean[0], pose[1] - mean[1], float(wrap(pose[2] - mean[2]))])
        return float(dev @ np.linalg.solve(cov, dev))

    @staticmethod
    def _mean_std(parts: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        mx = float(np.sum(w * parts[:, 0]))
        my = float(np.sum(w * parts[:, 1]))
        mt = float(np.angle(np.sum(w * np.exp(1j * parts[:, 2]))))
        dx, dy = parts[:, 0] - mx, parts[:, 1] - my
        dt = wrap(parts[:, 2] - mt)
        std = np.sqrt([np.sum(w * dx**2), np.sum(w * dy**2), np.sum(w * dt**2)])
        return np.array([mx, my, mt]), std

    def _realign(self, corrected: np.ndarray) -> int:
        """Re-align the records since the last correction so the last pose is ``corrected``;
        rebuild the map from the snapshot taken then. Returns the number of scans moved."""
        r = self._rec
        a, n = self._anchor_idx, len(r.poses)
        poses = np.array(r.poses[a:n])
        trav = np.array(r.travel[a:n])
        span = trav[-1] - trav[0]
        f = (trav - trav[0]) / span if span > 1e-9 else np.ones(len(trav))
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
        for i in range(a, n):
            r.poses[i] = new[i - a]
        grid = self._anchor.copy()
        self.cell_updates += self.model.integrate(grid, self._beams(a, n))
        self.grid = grid
        self._anchor = grid.copy()
        self._ref = grid.copy()
        self._anchor_idx = n
        self._ref_upto = n
        self._estimate = np.array(corrected, dtype=float)
        return n - a
