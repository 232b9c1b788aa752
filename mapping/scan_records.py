"""The scans behind sample-based data association (ir-grid-mapping §4, eq. 7-8), and
the nodes it closes loops on.

Every IR scan is kept with the pose it is mapped at (re-aligned in place when a
correction is accepted, fig. 11 e), the heading sigma of eq. 6, its ranges and kinds,
the distance travelled when it was taken and its stamp. From these records come:

- the beams of a span of scans, to insert into a grid (eq. 5-6);
- the window of eq. 7: the scans of the last ``window_m`` of travel (short-term odometry
  is good), at most ``AssociationConfig.window_scans`` of them (about ``window_beams``
  beams), as sensor poses in the current robot frame;
- the nodes: a scan every ``node_spacing_m`` of travel (fig. 11 b), and the node the
  sample cloud covers (a sample within ``cover_radius_m``, fig. 11 c) among those at
  least ``min_loop_m`` of travel back, the nearest to the current estimate.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from mapping.association_config import AssociationConfig
from mapping.ir_inverse import KIND_HIT, KIND_SKIP, Beams
from mapping.se2 import compose, relative


@dataclass
class ScanRecords:
    """Scans with their poses, for sensors at ``mounts`` (K, 3) on the robot; ``nodes``
    are indices of the node scans."""

    mounts: np.ndarray
    poses: list[np.ndarray] = field(default_factory=list)
    sigma: list[float] = field(default_factory=list)
    ranges: list[np.ndarray] = field(default_factory=list)
    kinds: list[np.ndarray] = field(default_factory=list)
    travel: list[float] = field(default_factory=list)
    stamps: list[int] = field(default_factory=list)
    nodes: list[int] = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.poses)

    def append(
        self,
        pose: np.ndarray,
        sigma: float,
        ranges: np.ndarray,
        kinds: np.ndarray,
        travel: float,
        stamp_ns: int,
    ) -> None:
        self.poses.append(pose)
        self.sigma.append(sigma)
        self.ranges.append(ranges)
        self.kinds.append(kinds)
        self.travel.append(travel)
        self.stamps.append(stamp_ns)

    def beams(self, start: int, stop: int, poses: np.ndarray | None = None) -> Beams:
        """The usable beams of scans ``start:stop`` in the world frame, taken at their
        recorded poses or at ``poses`` ((stop - start, 3): another branch's)."""
        if stop <= start:
            return Beams.concat([])
        poses = np.array(self.poses[start:stop]) if poses is None else np.asarray(poses)
        kinds = np.concatenate(self.kinds[start:stop])
        ranges = np.concatenate(self.ranges[start:stop])
        k = len(self.mounts)
        sens = compose(np.repeat(poses, k, axis=0), np.tile(self.mounts, (stop - start, 1)))
        sig = np.repeat(np.array(self.sigma[start:stop]), k)
        keep = kinds != KIND_SKIP
        return Beams(
            sens[keep, 0],
            sens[keep, 1],
            sens[keep, 2],
            np.where(kinds == KIND_HIT, ranges, np.nan)[keep],
            kinds[keep],
            sig[keep],
        )

    def beams_each(self, start: int, stop: int, poses: list[np.ndarray]) -> list[Beams]:
        """:meth:`beams` of scans ``start:stop`` at each of several pose sets ((stop -
        start, 3) each: the drift hypotheses'), sharing their range, kind and sigma arrays."""
        if stop <= start:
            return [Beams.concat([]) for _ in poses]
        kinds = np.concatenate(self.kinds[start:stop])
        ranges = np.concatenate(self.ranges[start:stop])
        k = len(self.mounts)
        mounts = np.tile(self.mounts, (stop - start, 1))
        keep = kinds != KIND_SKIP
        rng = np.where(kinds == KIND_HIT, ranges, np.nan)[keep]
        kind = kinds[keep]
        sig = np.repeat(np.array(self.sigma[start:stop]), k)[keep]
        out = []
        for p in poses:
            sens = compose(np.repeat(np.asarray(p), k, axis=0), mounts)
            out.append(Beams(sens[keep, 0], sens[keep, 1], sens[keep, 2], rng, kind, sig))
        return out

    def older_than(self, start: int, travel: float) -> int:
        """The end of the run of scans from ``start`` taken before ``travel``."""
        upto = start
        while upto < len(self.poses) and self.travel[upto] < travel:
            upto += 1
        return upto

    def window(
        self, estimate: np.ndarray, travel: float, cfg: AssociationConfig
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Sensor poses in the frame of ``estimate``, ranges and kinds of the window's
        beams (``travel``: the distance travelled now)."""
        n = len(self.poses)
        first = n - 1
        while first > 0 and self.travel[first - 1] >= travel - cfg.window_m:
            first -= 1
        scans = cfg.window_scans(len(self.mounts))
        idx = np.unique(np.linspace(first, n - 1, min(scans, n - first)).round())
        idx = idx.astype(int)
        poses = np.array([self.poses[i] for i in idx])
        rel = relative(estimate[None, :], poses)
        k = len(self.mounts)
        sens = compose(np.repeat(rel, k, axis=0), np.tile(self.mounts, (len(idx), 1)))
        ranges = np.concatenate([self.ranges[i] for i in idx])
        kinds = np.concatenate([self.kinds[i] for i in idx])
        keep = kinds != KIND_SKIP
        return sens[keep], ranges[keep], kinds[keep]

    def add_node_if_due(self, travel: float, spacing_m: float) -> None:
        """Make the latest scan a node if the last node is ``spacing_m`` back."""
        if not self.nodes or travel - self.travel[self.nodes[-1]] >= spacing_m:
            self.nodes.append(len(self.poses) - 1)

    def covered_node(
        self,
        particles: np.ndarray,
        estimate: np.ndarray,
        travel: float,
        cfg: AssociationConfig,
    ) -> int | None:
        """The node a sample lies near, at least ``min_loop_m`` back: the nearest to
        ``estimate``, or None."""
        best, best_d = None, math.inf
        for idx in self.nodes:
            if self.travel[idx] > travel - cfg.min_loop_m:
                break
            node = self.poses[idx]
            d = np.hypot(particles[:, 0] - node[0], particles[:, 1] - node[1])
            if d.min() <= cfg.cover_radius_m:
                dist = float(math.hypot(node[0] - estimate[0], node[1] - estimate[1]))
                if dist < best_d:
                    best, best_d = idx, dist
        return best
