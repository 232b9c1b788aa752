"""The sample-based data association's evidence as a pose graph (beyond ir-grid-mapping
§4): every loop closure the association has checked, not only the last ``reinsert_m``
of travel, straightens the whole trajectory at the end of a run.

The association re-aligns only the last few metres at an accepted correction (bounded
time and memory), so the map of a first exploration, drawn metres off by the wheels'
distance errors, stays where it was and later corrections align to it. Here:

- nodes: the scan at every ``graph_node_m`` of travel, and the scan of every check (the
  pose a loop edge ties);
- odometry edges between consecutive nodes: the dead-reckoned input step (the encoder
  positions with the fused heading, as the association moves its estimate), with a
  covariance in the frame of the first node that grows with the distance d and the
  turn: along the track (s^2 L + q^2) d, a distance scale error of sigma s
  (``graph_scale_sigma``: tyres, floor, load) that persists over ``graph_scale_length_m``
  taken as the random walk of the same variance over that length, plus the samples'
  position noise q (``position_noise_m_per_sqrt_m``); across the track q^2 d plus what
  the heading's variance over the step moves the end by (d^2 / 3 per rad^2); the
  heading's own variance, the growth of the heading filter's (at least its
  per-metre and per-radian floors);
- loop edges, from the checks whose posterior passed the association's guards (enough
  effective and distinct samples, :mod:`mapping.loop_correction`): a "confirmed" check
  (the uncorrected pose fits the map) at once, and a candidate when the held-out test
  accepts it (a candidate left "unconfirmed", a "worse" or "weak" check adds nothing).
  Each ties the check's scan to the earlier scan whose pass drew the walls the window
  matched (:meth:`LoopGraph.anchor`: the scans in the reference map vote with their
  hits within ``MATCH_M`` of the window's hits at the posterior's mean, by the stretch
  between two nodes); the walls drawn from a scan are rigid with its pose. The
  measurement is the posterior's mean in the frame of that scan's pose at the time,
  its covariance the posterior's (tempered: conservative) turned into that frame plus a
  floor for the map itself (a cell, 5 cm). The edges carry the position only
  (``LOOP_HEADING_SD``, 1 rad, added to the heading's variance): six IR beams over the
  1.5 m window say little about the heading, so the posterior's heading is mostly its
  prior's, the odometry the graph already holds (in the simulated room the checks'
  headings were off by 2-7 deg, one sigma of the posterior, all the same way). A
  robust (Cauchy) kernel keeps a wrong edge from bending the graph
  (:mod:`mapping.pose_graph`). An adopted drift re-poses the scans and rebuilds the map
  (:mod:`mapping.heading_drift`): each edge then keeps what its check found against the
  old map, its innovation over the old poses' relation, on the new poses' relation
  (:meth:`LoopGraph.rebase`);
- :meth:`LoopGraph.solve`: the graph optimised from the association's poses, and every
  scan re-posed between the two nodes around it along the recorded steps: the chain of
  steps from each of them, blended by the distance travelled. The association takes the
  result only if the map rebuilt at those poses is no less sharp than its own
  (:meth:`mapping.association.SampleAssociation.finish`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from mapping.association_config import AssociationConfig
from mapping.grid import GridConfig, OccupancyGrid
from mapping.ir_inverse import KIND_HIT, IrInverseModel
from mapping.pose_graph import PoseGraph
from mapping.scan_records import ScanRecords
from mapping.se2 import compose, relative, wrap

LOOP_HEADING_SD = 1.0  # rad: the loop edges carry no heading (module doc)
MATCH_M = 0.15  # a hit within 3 cells of one of the window's: the same wall
LOOP_FLOOR = np.array([0.05, 0.05, LOOP_HEADING_SD])  # a cell
HEADING_FLOOR_RAD2_PER_M = math.radians(0.1) ** 2
HEADING_FLOOR_RAD2_PER_RAD = math.radians(0.5) ** 2


@dataclass
class LoopGraph:
    """Nodes (scan indices) with the dead-reckoned poses, travel, turn and heading
    variance there; loop edges as (earlier scan, later scan, z, covariance)."""

    cfg: AssociationConfig
    scans: list[int] = field(default_factory=list)
    steps: list[np.ndarray] = field(default_factory=list)  # the input's step to every scan
    drift: list[float] = field(default_factory=list)  # the heading drift it is taken with
    travel: list[float] = field(default_factory=list)  # of every scan
    turn: list[float] = field(default_factory=list)  # accumulated |turn| at every scan
    var: list[float] = field(default_factory=list)  # heading filter variance at every scan
    hits: list[np.ndarray] = field(default_factory=list)  # (K, 2) robot-frame hits, NaN if none
    loops: list[tuple[int, int, np.ndarray, np.ndarray]] = field(default_factory=list)

    def record(self, step: np.ndarray, drift: float, travel: float, turn: float,
               var: float, hits: np.ndarray) -> None:  # fmt: skip
        """The scan just recorded: the input's step to it (the first: its pose) and the
        drift per radian turned it is corrected by (:mod:`mapping.heading_drift`), the
        travel, turn and heading variance; a node when ``graph_node_m`` of travel lies
        behind the last node."""
        self.steps.append(np.array(step, dtype=float))
        self.drift.append(drift)
        self.travel.append(travel)
        self.turn.append(turn)
        self.var.append(var)
        self.hits.append(hits)
        if not self.scans or travel - self.travel[self.scans[-1]] >= self.cfg.graph_node_m:
            self.scans.append(len(self.steps) - 1)

    def adopt(self, start: int, drift: float) -> None:
        """An adopted drift (:mod:`mapping.heading_drift`): the steps from scan ``start``
        on are taken with it, as the association re-aligned them."""
        for i in range(start, len(self.drift)):
            self.drift[i] = drift

    def rebase(self, old: list[np.ndarray], new: list[np.ndarray]) -> None:
        """The association re-posed its scans (an adopted drift: the map rebuilt at
        ``new`` poses from ``old``): each loop edge keeps what its check found against
        the map of the old poses, its innovation over the relation the old poses had, on
        the relation the new poses have."""
        out = []
        for a, b, z, cov in self.loops:
            innov = relative(relative(old[a], old[b]), z)
            out.append((a, b, compose(relative(new[a], new[b]), innov), cov))
        self.loops = out

    def dead_reckoned(self) -> np.ndarray:
        """(N, 3) the input's steps composed, each corrected by its drift."""
        out = np.empty((len(self.steps), 3))
        out[0] = self.steps[0]
        for i in range(1, len(self.steps)):
            st = self.steps[i]
            out[i] = compose(out[i - 1], np.array([st[0], st[1], st[2] * (1.0 - self.drift[i])]))
        return out

    def anchor(self, ends: np.ndarray, upto: int, poses: list[np.ndarray]) -> int | None:
        """The earlier scan whose pass drew the walls hit at ``ends`` (M, 2, world): the
        scans before ``upto`` vote with their hits within ``MATCH_M`` of one, by the
        stretch between two nodes; the scan with most votes in the stretch with most."""
        if upto <= 0 or len(ends) == 0:
            return None
        local = np.array(self.hits[:upto])  # (P, K, 2)
        p = np.array(poses[:upto])
        c, s = np.cos(p[:, 2])[:, None], np.sin(p[:, 2])[:, None]
        wx = p[:, 0:1] + c * local[..., 0] - s * local[..., 1]
        wy = p[:, 1:2] + s * local[..., 0] + c * local[..., 1]
        ok = np.isfinite(wx)
        scan_of = np.broadcast_to(np.arange(upto)[:, None], wx.shape)[ok]
        wx, wy = wx[ok], wy[ok]
        if len(wx) == 0:
            return None
        near = np.zeros(len(wx), dtype=bool)
        for e in ends:
            near |= (wx - e[0]) ** 2 + (wy - e[1]) ** 2 <= MATCH_M**2
        if not near.any():
            return None
        votes = np.bincount(scan_of[near], minlength=upto)
        nodes = np.array([n for n in self.scans if n < upto])
        seg = np.searchsorted(nodes, np.arange(upto), side="right") - 1
        best = int(np.argmax(np.bincount(seg, weights=votes)))
        return int(np.argmax(np.where(seg == best, votes, -1)))

    def loop_edge(
        self, scan: int, mean: np.ndarray, cov: np.ndarray, poses: list[np.ndarray],
        ends: np.ndarray,
    ) -> tuple[int, int, np.ndarray, np.ndarray] | None:  # fmt: skip
        """The loop edge of a check at ``scan`` whose posterior is (``mean``, ``cov``),
        ``poses``: the scans' poses now, ``ends``: the window's hits at the posterior's
        mean (module doc); None without an earlier scan that drew them."""
        far = self.travel[scan] - self.cfg.ref_lag_m
        upto = int(np.searchsorted(np.array(self.travel), far, side="right"))
        a = self.anchor(ends, min(upto, scan), poses)
        if a is None:
            return None
        anchor = poses[a]
        z = relative(anchor, mean)
        c, s = math.cos(anchor[2]), math.sin(anchor[2])
        j = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
        return a, scan, z, j @ cov @ j.T + np.diag(LOOP_FLOOR**2)

    def add_loop(self, edge: tuple[int, int, np.ndarray, np.ndarray] | None) -> None:
        if edge is not None:
            self.scans = sorted(set(self.scans) | {edge[0], edge[1]})
            self.loops.append(edge)

    def odometry_cov(self, odo: np.ndarray, a: int, b: int) -> tuple[np.ndarray, np.ndarray]:
        """(z, covariance) of the odometry edge from scan a to scan b (``odo``: the
        dead-reckoned poses; module doc)."""
        cfg = self.cfg
        z = relative(odo[a], odo[b])
        d = self.travel[b] - self.travel[a]
        turn = self.turn[b] - self.turn[a]
        q2 = cfg.position_noise_m_per_sqrt_m**2
        vth = (max(self.var[b] - self.var[a], 0.0) + HEADING_FLOOR_RAD2_PER_M * d
               + HEADING_FLOOR_RAD2_PER_RAD * turn)  # fmt: skip
        along = (cfg.graph_scale_sigma**2 * cfg.graph_scale_length_m + q2) * d + 1e-8
        across = q2 * d + vth * d * d / 3.0 + 1e-8
        chord = math.hypot(z[0], z[1])
        u = z[:2] / chord if chord > 1e-9 else np.array([1.0, 0.0])
        rot = np.array([[u[0], -u[1]], [u[1], u[0]]])
        cov = np.zeros((3, 3))
        cov[:2, :2] = rot @ np.diag([along, across]) @ rot.T
        cov[2, 2] = vth + 1e-10
        return z, cov

    def solve(self, poses: list[np.ndarray]) -> np.ndarray | None:
        """The scans' poses (N, 3) from the optimised graph, started from ``poses`` (the
        association's); None without a loop edge."""
        n = len(self.steps)
        if not self.loops or n < 2:
            return None
        odo = self.dead_reckoned()
        nodes = sorted(set(self.scans) | {n - 1})
        index = {s: k for k, s in enumerate(nodes)}
        g = PoseGraph()
        for s in nodes:
            g.add_node(poses[s])
        for a, b in zip(nodes[:-1], nodes[1:], strict=True):
            z, cov = self.odometry_cov(odo, a, b)
            g.add_edge(index[a], index[b], z, np.linalg.inv(cov))
        for a, b, z, cov in self.loops:
            g.add_edge(index[a], index[b], z, np.linalg.inv(cov), robust=True)
        x = g.optimize().poses
        return self._repose(nodes, x, odo)

    def _repose(self, nodes: list[int], x: np.ndarray, odo: np.ndarray) -> np.ndarray:
        """Every scan between two nodes along the recorded steps, from each node's new
        pose, blended by the distance travelled (module doc)."""
        trav = np.array(self.travel)
        out = np.empty_like(odo)
        for k in range(len(nodes) - 1):
            a, b = nodes[k], nodes[k + 1]
            idx = np.arange(a, b + 1)
            pa = compose(np.broadcast_to(x[k], (len(idx), 3)), relative(odo[a], odo[idx]))
            pb = compose(np.broadcast_to(x[k + 1], (len(idx), 3)), relative(odo[b], odo[idx]))
            span = trav[b] - trav[a]
            f = (trav[idx] - trav[a]) / span if span > 1e-9 else (idx - a) / max(b - a, 1)
            out[idx, :2] = (1 - f)[:, None] * pa[:, :2] + f[:, None] * pb[:, :2]
            out[idx, 2] = pa[:, 2] + f * wrap(pb[:, 2] - pa[:, 2])
        out[nodes[-1]] = x[-1]
        return out


def scan_hits(mounts: np.ndarray, ranges: np.ndarray, kinds: np.ndarray) -> np.ndarray:
    """A scan's hits in the robot frame, (K, 2); NaN where a beam hit nothing."""
    rng = np.where(kinds == KIND_HIT, ranges, np.nan)
    return np.column_stack(
        [mounts[:, 0] + rng * np.cos(mounts[:, 2]), mounts[:, 1] + rng * np.sin(mounts[:, 2])]
    )


def window_ends(
    mean: np.ndarray, sens: np.ndarray, ranges: np.ndarray, kinds: np.ndarray
) -> np.ndarray:
    """The window's hits in the world at the posterior's mean ``mean`` (sensor poses
    ``sens`` in the robot frame at each scan of the window), (H, 2)."""
    hit = kinds == KIND_HIT
    at = compose(np.broadcast_to(mean, sens.shape), sens)[hit]
    return at[:, :2] + ranges[hit][:, None] * np.column_stack([np.cos(at[:, 2]), np.sin(at[:, 2])])


def rebuilt_map(
    rec: ScanRecords, poses: np.ndarray, model: IrInverseModel, config: GridConfig,
    batch: int = 200,
) -> tuple[OccupancyGrid, int]:  # fmt: skip
    """Every recorded scan inserted again at ``poses`` into a new grid, ``batch`` scans
    at a time (bounded memory); the grid and its cell updates."""
    grid, updates = OccupancyGrid(config), 0
    for a in range(0, len(rec), batch):
        b = min(a + batch, len(rec))
        updates += model.integrate(grid, rec.beams(a, b, poses[a:b]), "off")
    return grid, updates


def occupied_cells(grid: OccupancyGrid) -> int:
    """The cells a map calls occupied (its walls' extent: the same walls drawn from
    poses that agree take fewer)."""
    return int((grid.trinary() == 1).sum())


def graph_map(
    graph: LoopGraph | None,
    rec: ScanRecords,
    grid: OccupancyGrid,
    model: IrInverseModel,
    config: GridConfig | None,
) -> tuple[str, np.ndarray | None, OccupancyGrid | None, int]:
    """The graph's answer at the end of a run (:meth:`mapping.association.
    SampleAssociation.finish`): (what it did, the re-posed scans, their map, the cell
    updates spent). The poses and map are None when the association's stay: no loop
    edge, a map at the graph's poses that would need more than ``max_cells``, or one
    that draws the walls in more occupied cells than ``grid``."""
    new = graph.solve(rec.poses) if graph is not None else None
    if new is None:
        return ("no loop edge" if graph is not None else "off"), None, None, 0
    assert graph is not None
    try:
        rebuilt, updates = rebuilt_map(rec, new, model, config)
    except ValueError as e:  # the graph's poses need more than max_cells
        return f"kept the association's map (the graph's map: {e})", None, None, 0
    occ_old, occ_new = occupied_cells(grid), occupied_cells(rebuilt)
    what = (f"{len(graph.loops)} loop edges, {len(set(graph.scans))} nodes: "
            f"occupied cells {occ_old} -> {occ_new}")  # fmt: skip
    if occ_new > occ_old:
        return f"kept the association's map ({what})", None, None, updates
    return f"re-posed ({what})", new, rebuilt, updates
