"""EKF localization of the MRCLAM robots (real data), alone or cooperative, for the
comparison with CP (issue 14 item 4): the batch runner over a whole run. Every model and
default is derived in docs/algorithms.md ("EKF on the MRCLAM robots"); in short:

**State and motion.** Per robot (x, y, theta, k, b, c, d, beta): the pose (theta
continuous), a speed scale error and a turn-rate bias (Gauss-Markov,
localization/mrclam_motion.py), and the camera's range scale error, range offset and
bearing offset (random walks, localization/mrclam_camera.py). The odometry is the
commanded (v, w), applied ``command_lag_s`` = 0.18 s after its stamp and held.

**Camera.** It reports the depth along its optical axis, (1 + c) r cos(psi) + d, and the
bearing psi = phi + beta; noise from the errors left by that model (range: a floor and
the depth quantisation growing as r^2; bearing: a floor and a lateral error / r),
inflated for the errors' correlation in time (AR(1), integral scale 8 s) and within a
camera frame. Gate: NIS with the uninflated noise above chi2_2(p) -> counted and named
(``EkfTrack.gated``), not used.

**Robots** (``cooperation``): "joint" (default) runs one filter over all the robots with
their cross-covariances (the centralized equivalent: exact, and consistent under the
model); "split_ci" and "ci" run one filter per robot that sees only the others'
published estimates (their track's latest grid row, as in the replay), fused by split
covariance intersection (the camera noise independent) or covariance intersection, the
observed robot updated too from the observer's position fix of it (``peer_update``
"both"); "none" (or ``cooperative=False``) uses landmarks only.

**Pure**: one deterministic pass over the merged stream of every robot's odometry and
measurements in stamp order (at one stamp: odometry, landmarks, robots; robot by robot),
as ``hilnav import mrclam`` orders a log: the replay service
(localization/mrclam_service.py) drives the same steps (localization/mrclam_filter.py)
message by message and gives the same track. No threads, no clocks.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from localization.mrclam import MrclamRun, RobotRun
from localization.mrclam_config import MrclamEkfConfig
from localization.mrclam_filter import JointEkf, ar1_inflation
from localization.mrclam_track import EkfTrack, score_track

__all__ = [
    "EkfTrack",
    "MrclamEkfConfig",
    "ar1_inflation",
    "initial_pose",
    "log_time",
    "run_ekf",
    "score_track",
]

ODOMETRY, LANDMARK, ROBOT = 0, 1, 2


def initial_pose(robot: RobotRun, t: float) -> np.ndarray:
    """The motion-capture sample nearest to ``t`` (what ``hilnav import mrclam`` writes
    as the robot's ``initial_pose``)."""
    i = int(np.argmin(np.abs(robot.truth[:, 0] - t)))
    return robot.truth[i, 1:].astype(float)


def log_time(t: np.ndarray) -> np.ndarray:
    """Data set seconds as a log's stamps give them back: read to the microsecond in
    integer ns (``hilnav import mrclam``), times 1e-9, so that the batch and the replay
    service see the very same floats (and tie the same way)."""
    return (np.round(np.asarray(t, float) * 1e6).astype(np.int64) * 1000) * 1e-9


def _events(run: MrclamRun, robots: list[int]) -> np.ndarray:
    """Rows (time, kind, robot, seq, a, b, c) in the order of an imported log: kind
    ODOMETRY (a = v, b = w), LANDMARK or ROBOT (a = subject, b = range, c = bearing);
    times as :func:`log_time` gives them."""
    rows = []
    for n in robots:
        o = run.robots[n].odometry
        z = np.zeros(len(o))
        rows.append(np.column_stack([o[:, 0], z, z + n, np.arange(len(o)), o[:, 1:], z]))
        m = run.robots[n].measurements
        kind = np.where(np.isin(m[:, 1], list(run.landmarks)), LANDMARK, ROBOT)
        rows.append(np.column_stack([m[:, 0], kind, kind * 0 + n, np.arange(len(m)), m[:, 1:]]))
    ev = np.concatenate(rows)
    ev[:, 0] = log_time(ev[:, 0])
    return ev[np.lexsort((ev[:, 3], ev[:, 2], ev[:, 1], ev[:, 0]))]


def _track(n: int, f: JointEkf) -> EkfTrack:
    rs = f.r[n]
    rows = rs.rows
    t = np.array([r[0] for r in rows])
    mean = np.array([r[1] for r in rows]).reshape(-1, 3)
    cov = np.array([r[2] for r in rows]).reshape(-1, 3, 3)
    grid = np.array([r[3] for r in rows], bool)
    return EkfTrack(n, t, mean, cov, rs.counts, rs.gated, grid)


def run_ekf(
    run: MrclamRun,
    robots: list[int] | None = None,
    cooperative: bool = True,
    config: MrclamEkfConfig | None = None,
) -> dict[int, EkfTrack]:
    """EKF tracks of ``robots`` (default all) over the whole run; see the module doc.

    Each robot starts at its first odometry stamp, at the motion-capture sample nearest
    to it with ``init_sigma``, at rest until its first command acts. Measurements of a
    subject that is neither a landmark of the map nor a robot being run, non-finite or
    non-positive ranges, and measurements stamped before the robot's start are counted
    (``EkfTrack.counts``) and skipped; so are robot-robot measurements when
    ``cooperative`` is False (``cooperation = "none"``).
    """
    cfg = config or MrclamEkfConfig()
    if not cooperative:
        cfg = replace(cfg, cooperation="none")
    ids = sorted(run.robots) if robots is None else list(dict.fromkeys(robots))
    for n in ids:
        if n not in run.robots:
            raise ValueError(f"robot {n} is not in {run.directory} (has {sorted(run.robots)})")
    joint = cfg.cooperation == "joint"
    shared = JointEkf(cfg, run.landmarks) if joint else None
    filters: dict[int, JointEkf] = {}
    init_cov = np.diag(np.square(np.asarray(cfg.init_sigma, float)))
    for n in ids:
        f = shared if shared is not None else JointEkf(cfg, run.landmarks)
        t0 = float(log_time(run.robots[n].odometry[:1, 0])[0])
        f.add_robot(n, t0, initial_pose(run.robots[n], t0), init_cov)
        filters[n] = f
    both = cfg.peer_update == "both"
    ev = _events(run, ids)
    for t, kind, rn, _, a, b, c in ev.tolist():
        n = int(rn)
        f = filters[n]
        rs = f.r[n]
        if kind == ODOMETRY:
            f.command(n, t, a, b)
            f.process_to(n, t)
            continue
        if t < rs.t0:
            rs.counts["before_start"] += 1
            continue
        if not (math.isfinite(b) and math.isfinite(c) and b > 0.0):
            f.process_to(n, t)
            rs.counts["invalid"] += 1
            continue
        subj, z = int(a), np.array([b, c])
        if kind == LANDMARK:
            f.landmark(n, t, subj, z)
        elif subj in filters and subj != n:
            if t < filters[subj].r[subj].t0:
                f.process_to(n, t)
                rs.counts["robot_not_started"] += 1
            elif cfg.cooperation == "none":
                f.process_to(n, t)
                rs.counts["robot_ignored"] += 1
            elif joint:
                f.robot_joint(n, t, subj, z)
            else:
                fix = f.robot_split(n, t, subj, z, filters[subj].r[subj].last_grid, both)
                if fix is not None:
                    filters[subj].fix_update(subj, fix)
        else:
            f.process_to(n, t)
            rs.counts["robot_not_run" if subj in run.robots else "unknown_subject"] += 1
    end = float(ev[-1, 0]) if len(ev) else run.start_s
    for n in ids:
        filters[n].process_to(n, end)
    return {n: _track(n, filters[n]) for n in ids}
