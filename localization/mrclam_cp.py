"""Guaranteed (CP) localization of every robot of an MRCLAM run, alone or cooperatively
(issue 14 items 2, 3 and 6): one deterministic pass over the merged, time-ordered stream
of all robots' odometry and measurements, in one process.

Each robot runs a :class:`~localization.cp_rb.RangeBearingCP`. Landmark sightings
(subjects 6-20) are observations against the known map. Cooperatively, a sighting of a
robot (subjects 1-5) is also used: the observer uses the peer's last *published* box,
aged by its stamp (``peer_seen``), and then sends the measurement with its own fresh box
to the peer, which uses it as an observation of itself (``seen_by``) at its next solve. A robot publishes
its box after each solve and at every tick (``tick_s``). Alone, robot sightings are
ignored.

Events at the same instant run in a fixed order (ticks, then observations; robots by
subject #), so a run is reproducible bit for bit. Ticks are where the boxes are reported
(and scored): every ``tick_s`` from the run's start, each robot's box predicted from its
latest solved state; they are computed in bulk at the end (:func:`predict_hulls`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from localization.cp_config import RangeBearingCPConfig
from localization.cp_rb import PeerBox, RangeBearingCP
from localization.mrclam import MrclamRun
from localization.velocity_odometry import predict_boxes, predict_hulls

_INF = np.inf


@dataclass
class CpTrack:
    """One robot's reported boxes: at ticks ``t`` (N,), ``box`` (N, 2, 3) (lo/hi of x,
    y, heading; heading unwrapped), ``status`` (N,) and ``age`` (N,: seconds since the
    solved state the box is predicted from; inf before the first) per tick; the
    observations named inconsistent, the fallback events, and the solver's counters."""

    t: np.ndarray
    box: np.ndarray
    status: np.ndarray
    age: np.ndarray
    outliers: list[tuple[float, str, int]]
    events: list[tuple[float, str]]
    solves: int
    observations: int


def _groups(meas: np.ndarray) -> list[tuple[float, np.ndarray]]:
    """Measurements grouped by stamp."""
    if len(meas) == 0:
        return []
    cut = np.flatnonzero(np.diff(meas[:, 0]) != 0.0) + 1
    return [(float(g[0, 0]), g) for g in np.split(meas, cut)]


def run_cp(
    run: MrclamRun,
    robots: list[int] | None = None,
    cooperative: bool = True,
    config: RangeBearingCPConfig | None = None,
    tick_s: float = 0.1,
    end_s: float | None = None,
    start_s: float | None = None,
) -> dict[int, CpTrack]:
    """CP over ``run`` (seconds on the data's clock; ``start_s`` and ``end_s`` cut it:
    the robots start knowing nothing at ``start_s``)."""
    cfg = config or RangeBearingCPConfig()
    ids = sorted(run.robots if robots is None else robots)
    t0 = run.start_s if start_s is None else max(run.start_s, start_s)
    t1 = run.end_s if end_s is None else min(run.end_s, end_s)
    cps = {r: RangeBearingCP(cfg, run.landmarks, r) for r in ids}
    # Non-command events: (t, order, robot, payload). order 0: tick, 1: observations.
    events: list[tuple[float, int, int, object]] = []
    ticks = np.arange(t0, t1 + 1e-9, tick_s)
    for r in ids:
        events += [(float(t), 0, r, None) for t in ticks]
        for t, g in _groups(run.robots[r].measurements):
            if t0 <= t <= t1:
                events.append((t, 1, r, g))
    events.sort(key=lambda e: (e[0], e[1], e[2]))
    odo = {r: run.robots[r].odometry for r in ids}
    nxt = {r: max(0, int(np.searchsorted(odo[r][:, 0], t0 - cfg.command_lag_s)) - 1) for r in ids}
    published: dict[int, object] = {}  # robot -> PeerBox, or a snapshot to compute one from
    snaps: dict[int, list] = {r: [] for r in ids}
    n_obs = dict.fromkeys(ids, 0)

    def feed(r: int, t: float) -> None:
        o, i = odo[r], nxt[r]
        j = int(np.searchsorted(o[:, 0], t, side="right"))
        cp = cps[r]
        for k in range(i, j):
            cp.command(o[k, 0], o[k, 1], o[k, 2])
        nxt[r] = j

    def peer_box(r: int) -> PeerBox | None:
        p = published.get(r)
        if p is None or isinstance(p, PeerBox):
            return p
        box = peer_pieces(p, cfg)
        published[r] = box
        return box

    def publish(r: int) -> None:
        snap = cps[r].snapshot()
        if snap is not None:
            published[r] = snap

    for t, kind, r, g in events:
        feed(r, t)
        cp = cps[r]
        cp.advance(t)
        if kind == 0:
            snaps[r].append((t, cp.snapshot()))
            publish(r)
            continue
        obs, seen = [], []
        for _, subject, rng, brg in g:
            s = int(subject)
            if s not in run.robots:
                obs.append(cp.landmark(t, s, rng, brg))
            elif cooperative and s in cps:
                box = peer_box(s)
                if box is not None:
                    obs.append(cp.peer_seen(t, s, rng, brg, box))
                seen.append((s, rng, brg))
        obs = [o for o in obs if o is not None]
        n_obs[r] += len(obs)
        if obs:
            cp.observe(t, obs)
        if obs or seen:  # the box at t: what the peers it saw hear it with
            publish(r)
        for s, rng, brg in seen:  # the peer hears of it, with this robot's box at t
            mine = peer_box(r)
            if mine is not None:
                cps[s].hear(r, rng, brg, mine)
                n_obs[s] += 1
    return {r: _track(cps[r], snaps[r], cfg, n_obs[r]) for r in ids}


def peer_pieces(snap: tuple, cfg: RangeBearingCPConfig) -> PeerBox:
    """The box a robot publishes from its :meth:`RangeBearingCP.snapshot`: each piece of
    its latest solved state predicted to the snapshot's instant, their hull and the
    pieces themselves (a peer uses the pieces: they keep heading and position coupled)."""
    t, theta0, b, st, _, alert = snap
    out = predict_boxes(b, np.full(b.shape[0], theta0), [st] * b.shape[0], cfg)
    lo, hi = out[:, 0].min(axis=0), out[:, 1].max(axis=0)
    pieces = tuple(tuple(float(v) for v in o.T.ravel()) for o in out)
    return PeerBox(t, (lo[0], hi[0]), (lo[1], hi[1]), (lo[2], hi[2]), alert, pieces)


def _track(cp: RangeBearingCP, snaps: list, cfg: RangeBearingCPConfig, n_obs: int) -> CpTrack:
    n = len(snaps)
    t = np.array([s[0] for s in snaps])
    box = np.empty((n, 2, 3))
    box[:, 0], box[:, 1] = -_INF, _INF
    status = np.array(["unknown"] * n, dtype=object)
    age = np.full(n, np.inf)
    idx = [i for i, (_, s) in enumerate(snaps) if s is not None]
    if idx:
        b = [snaps[i][1][2] for i in idx]
        theta0 = np.array([snaps[i][1][1] for i in idx])
        steps = [snaps[i][1][3] for i in idx]
        box[idx] = predict_hulls(b, theta0, steps, cfg)
        status[idx] = [snaps[i][1][4] for i in idx]
        age[idx] = [snaps[i][1][3].dt for i in idx]
    return CpTrack(t, box, status, age, list(cp.outliers), list(cp.events), cp.solves, n_obs)


def containment(track: CpTrack, truth: np.ndarray) -> np.ndarray:
    """Per tick: the truth pose (N, 3) inside the box (heading modulo 2 pi)."""
    b = track.box
    two_pi = 2.0 * np.pi
    inx = (b[:, 0, 0] <= truth[:, 0]) & (truth[:, 0] <= b[:, 1, 0])
    iny = (b[:, 0, 1] <= truth[:, 1]) & (truth[:, 1] <= b[:, 1, 1])
    lo, hi = b[:, 0, 2], b[:, 1, 2]
    with np.errstate(invalid="ignore"):
        first = truth[:, 2] + two_pi * np.ceil((lo - truth[:, 2]) / two_pi)
        inth = (hi - lo >= two_pi) | (first <= hi)
    return inx & iny & inth
