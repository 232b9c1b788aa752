"""``hilnav import mrclam``: a UTIAS MRCLAM run as a multi-robot hilnav MCAP log.

Uses the MRCLAM loader (``localization.mrclam.load_mrclam``: barcodes translated to
subjects, unknown barcodes dropped and counted, over the whole files). Robot subject n is the robot ``r<n>``,
landmark subject n is the target ``l<n>``. Per robot, with log time = publish time =
the message's stamp (the data set's clock in ns, read to the microsecond):

| topic | message | rate |
|---|---|---|
| ``/r<n>/landmark_map`` | msgs.LandmarkMap: the 15 surveyed landmarks (ids = subjects, covariance from their std-devs) | once, at the log's start |
| ``/r<n>/velocity`` | msgs.VelocityOdometry (commanded forward speed and yaw rate) | ~67 Hz |
| ``/r<n>/landmark_range_bearing`` | msgs.RangeBearing to a landmark (``landmark`` true, target ``l<subject>``) | camera |
| ``/r<n>/peer_range_bearing`` | msgs.RangeBearing to another robot (target ``r<subject>``) | camera |
| ``/r<n>/truth`` | msgs.GroundTruth (motion capture); ``gap_before_s`` > 0 after a gap | ~100 Hz |

Truth gaps: a truth sample that follows the previous one of the file by more than the
loader's ``MAX_TRUTH_GAP_S`` (0.25 s) carries ``gap_before_s`` = that gap; ``hilnav
analyze`` scores no instant inside it. Measurements of a robot to itself, or to a subject
that is neither a landmark of the map nor a robot of the run, are dropped and counted.

The log starts at the run's start (the first odometry message of the robots imported;
the motion capture runs some seconds before it, those samples are left out) plus
``start_s``, and holds ``seconds`` from there (all when None). Messages at one stamp go
in the order map, truth, velocity, landmark, peer, robot by robot.

The "hilnav" metadata: ``dataset`` "mrclam", ``robots`` ("r1,r2,..."), ``reference``
"truth", and ``initial_pose.r<n>`` = "x,y,theta": the motion-capture pose nearest to the
robot's first odometry message of the log, what a robot's config ``initial_pose`` says
(the services of ``hilnav replay`` start from it).
"""

from __future__ import annotations

import heapq
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from hilnav.log.writer import LogWriter
from hilnav.topics import log_topic
from msgs import GroundTruth, LandmarkMap, Pose2D, RangeBearing, VelocityOdometry, wrap_angle

TOPICS = ("landmark_map", "truth", "velocity", "landmark_range_bearing", "peer_range_bearing")
_ORDER = {t: i for i, t in enumerate(TOPICS)}


def robot_name(subject: int) -> str:
    return f"r{subject}"


def landmark_name(subject: int) -> str:
    return f"l{subject}"


@dataclass
class MrclamImportReport:
    source: str
    output: str
    robots: list[str]
    counts: dict[str, Counter] = field(default_factory=dict)  # robot -> topic -> messages
    truth_gaps: dict[str, list[float]] = field(default_factory=dict)  # robot -> gaps (s)
    dropped: Counter = field(default_factory=Counter)
    first_ns: int = 0
    last_ns: int = 0

    def as_dict(self) -> dict[str, Any]:
        total: Counter = Counter()
        for c in self.counts.values():
            total.update(c)
        return {
            "source": self.source,
            "output": self.output,
            "robots": self.robots,
            "messages": dict(sorted(total.items())),
            "per_robot": {r: dict(sorted(c.items())) for r, c in sorted(self.counts.items())},
            "truth_gaps": {
                r: {"count": len(g), "total_s": round(sum(g), 3), "longest_s": max(g, default=0)}
                for r, g in sorted(self.truth_gaps.items())
            },
            "dropped": dict(sorted(self.dropped.items())),
            "first_ns": self.first_ns,
            "last_ns": self.last_ns,
            "duration_s": round((self.last_ns - self.first_ns) / 1e9, 3),
        }


def landmark_map(
    landmarks: dict[int, tuple[float, float, float, float]], stamp_ns: int
) -> LandmarkMap:
    """The run's surveyed landmarks (subject -> x, y, std-dev x, std-dev y) as a
    msgs.LandmarkMap (ids = subjects, covariance from the std-devs)."""
    ids = sorted(landmarks)
    return LandmarkMap(
        stamp_ns,
        tuple(ids),
        tuple(landmarks[i][0] for i in ids),
        tuple(landmarks[i][1] for i in ids),
        tuple(landmarks[i][2] ** 2 for i in ids),
        tuple(0.0 for _ in ids),
        tuple(landmarks[i][3] ** 2 for i in ids),
    )


def to_ns(t_s: np.ndarray) -> np.ndarray:
    """Data set seconds -> integer ns, read to the microsecond (the files hold ms)."""
    return np.round(np.asarray(t_s, dtype=float) * 1e6).astype(np.int64) * 1000


Item = tuple[int, int, int, int, str, Any]  # stamp, topic order, robot index, seq, topic, msg


def _items(order_topic: str, ridx: int, stamps: np.ndarray, make) -> Iterator[Item]:
    order = _ORDER[order_topic]
    for seq, st in enumerate(stamps.tolist()):
        topic, msg = make(seq, st)
        yield (st, order, ridx, seq, topic, msg)


def _window(ns: np.ndarray, lo: int, hi: int | None) -> np.ndarray:
    keep = ns >= lo
    return keep & (ns <= hi) if hi is not None else keep


def import_mrclam(
    directory: str | Path,
    out: str | Path,
    seconds: float | None = None,
    start_s: float = 0.0,
    robots: list[int] | None = None,
    compression: str = "zstd",
) -> MrclamImportReport:
    """Write the run (or ``seconds`` of it from ``start_s`` after its start) to ``out``."""
    from localization.mrclam import MAX_TRUTH_GAP_S, load_mrclam, robot_subjects

    run = load_mrclam(directory, robots)  # MrclamError (a ValueError) names the problem
    present = set(robot_subjects(directory))
    subjects = sorted(run.robots)
    names = [robot_name(n) for n in subjects]
    lo = int(to_ns(np.array([run.start_s]))[0]) + int(round(start_s * 1e9))
    hi = lo + int(round(seconds * 1e9)) if seconds is not None else None
    rep = MrclamImportReport(str(directory), str(out), names)
    rep.dropped.update(run.dropped)
    ids = sorted(run.landmarks)
    lmap = landmark_map(run.landmarks, lo)
    streams: list[Iterator[Item]] = []
    meta = {
        "dataset": "mrclam",
        "source": Path(directory).name,
        "robots": ",".join(names),
        "plan": "",
        "reference": "truth",
        "truth_max_gap_s": str(MAX_TRUTH_GAP_S),
        "start_ns": str(lo),
        "seconds": "" if seconds is None else str(seconds),
    }
    gap_ns = int(MAX_TRUTH_GAP_S * 1e9)
    for ridx, (n, name) in enumerate(zip(subjects, names, strict=True)):
        rr = run.robots[n]
        counts = rep.counts.setdefault(name, Counter())
        # velocity odometry
        odo_ns = to_ns(rr.odometry[:, 0])
        k = _window(odo_ns, lo, hi)
        odo, ons = rr.odometry[k], odo_ns[k]
        counts["velocity"] = int(k.sum())

        def velocity(i: int, st: int, odo=odo) -> tuple[str, Any]:
            return "velocity", VelocityOdometry(st, float(odo[i, 1]), float(odo[i, 2]), True)

        streams.append(_items("velocity", ridx, ons, velocity))
        # truth, gaps flagged against the previous sample of the whole file
        tr_ns = to_ns(rr.truth[:, 0])
        gaps = np.concatenate([[0], np.diff(tr_ns)])
        gaps = np.where(gaps > gap_ns, gaps, 0)
        k = _window(tr_ns, lo, hi)
        tr, tns, tgap = rr.truth[k], tr_ns[k], gaps[k]
        counts["truth"] = int(k.sum())
        rep.truth_gaps[name] = [round(g * 1e-9, 3) for g in tgap[tgap > 0].tolist()]

        def truth(i: int, st: int, tr=tr, tgap=tgap, name=name) -> tuple[str, Any]:
            pose = Pose2D(float(tr[i, 1]), float(tr[i, 2]), wrap_angle(float(tr[i, 3])))
            return "truth", GroundTruth(st, name, pose, gap_before_s=float(tgap[i]) * 1e-9)

        streams.append(_items("truth", ridx, tns, truth))
        # measurements: landmarks and robots
        m_ns = to_ns(rr.measurements[:, 0])
        k = _window(m_ns, lo, hi)
        meas, mns = rr.measurements[k], m_ns[k]
        subj = meas[:, 1].astype(int)
        is_lm = np.isin(subj, ids)
        is_rb = ~is_lm & np.isin(subj, sorted(present - {n}))
        rep.dropped[f"{name}_self_measurement"] += int(np.sum(subj == n))
        rep.dropped[f"{name}_unknown_subject"] += int(np.sum(~is_lm & ~is_rb & (subj != n)))
        for topic, sel, tname, landmark in (
            ("landmark_range_bearing", is_lm, landmark_name, True),
            ("peer_range_bearing", is_rb, robot_name, False),
        ):
            ms, ss = meas[sel], subj[sel]
            counts[topic] = int(sel.sum())

            def rb(i: int, st: int, ms=ms, ss=ss, topic=topic, tname=tname, lmk=landmark, me=name):
                s = int(ss[i])
                m = RangeBearing(st, me, tname(s), lmk, float(ms[i, 2]), float(ms[i, 3]), s)
                return topic, m

            streams.append(_items(topic, ridx, mns[sel], rb))
        counts["landmark_map"] = 1
        streams.append(
            _items("landmark_map", ridx, np.array([lo]), lambda i, st: ("landmark_map", lmap))
        )
        # the pose a robot's config would give: the truth nearest its first odometry
        t_first = int(ons[0]) if len(ons) else lo
        j = int(np.argmin(np.abs(tr_ns - t_first)))
        x, y, th = (float(v) for v in rr.truth[j, 1:])
        meta[f"initial_pose.{name}"] = f"{x!r},{y!r},{wrap_angle(th)!r}"
    rep.dropped = Counter({k: v for k, v in rep.dropped.items() if v})
    first = True
    with LogWriter(out, compression=compression, metadata=meta, wall_clock=False) as w:
        for stamp, _, ridx, _, topic, msg in heapq.merge(*streams):
            if first:
                rep.first_ns, first = stamp, False
            w.write(log_topic(names[ridx], topic), msg, stamp)
            rep.last_ns = stamp
    return rep
