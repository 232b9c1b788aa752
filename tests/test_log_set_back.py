"""A log whose time goes back (the recording host's clock was set back): read in the order
it was written, so a replay takes its messages as they happened (not the two stretches
interleaved by log time), and the analysis says so."""

from __future__ import annotations

import math
from pathlib import Path

from hilnav.analysis.analyze import analyze
from hilnav.analysis.report import digest
from hilnav.config import load_config
from hilnav.log.reader import ReadStats, iter_raw, read_messages
from hilnav.log.writer import LogWriter
from hilnav.pipeline import Pipeline
from hilnav.replay.replayer import replay
from tests.test_pipeline import drive

S = 1_000_000_000


def _write(path: Path, back_s: float) -> None:
    """The pipeline's inputs of a 20 s drive, the stamps (and log times) after 10 s set
    back by ``back_s``."""
    import dataclasses

    inputs, _ = drive(seconds=20.0)
    shift = int(back_s * S)
    with LogWriter(path, metadata={"robot": "r1", "plan": "office"}, wall_clock=False) as w:
        for topic, msg in inputs:
            if msg.stamp_ns > 10 * S:
                msg = dataclasses.replace(msg, stamp_ns=msg.stamp_ns - shift)
            w.write(f"/r1/{topic}", msg, msg.stamp_ns)


def test_a_log_whose_time_goes_back_is_read_and_replayed_in_the_order_written(
    tmp_path: Path,
) -> None:
    clean, back = tmp_path / "clean.mcap", tmp_path / "back.mcap"
    _write(clean, 0.0)
    _write(back, 8.0)
    st_clean, st_back = ReadStats(), ReadStats()
    t_clean = [r.log_time_ns for r in iter_raw(clean, stats=st_clean, as_written=True)]
    t_back = [r.log_time_ns for r in iter_raw(back, stats=st_back, as_written=True)]
    assert st_clean.set_backs == 0 and t_clean == sorted(t_clean)
    assert st_back.set_backs == 1 and len(t_back) == len(t_clean)
    by_time = [r.log_time_ns for r in iter_raw(back)]  # log cat, info: log-time order
    assert by_time == sorted(by_time)
    i = next(k for k in range(1, len(t_back)) if t_back[k] < t_back[k - 1] - S)
    assert t_back[:i] == sorted(t_back[:i]) and t_back[i:] == sorted(t_back[i:])  # 2 stretches
    outs = {}
    for name, src in (("clean", clean), ("back", back)):
        rep = replay(src, tmp_path / f"{name}-replay.mcap", progress=False,
                     pipeline_factory=Pipeline, config=load_config(None))  # fmt: skip
        assert rep.read["set_backs"] == (name == "back")
        heads = [m.msg for m in read_messages(tmp_path / f"{name}-replay.mcap",
                                                  topics=["/r1/heading"])]  # fmt: skip
        outs[name] = heads[-1]
    a, b = outs["clean"], outs["back"]
    assert b.stamp_ns == a.stamp_ns - 8 * S  # it went on to the end
    assert abs(math.remainder(a.theta_rad - b.theta_rad, 2 * math.pi)) < math.radians(1.0)
    # the odometry steps until the set back is confirmed are lost: 12 cm at 0.4 m/s
    assert math.hypot(a.pose.x - b.pose.x, a.pose.y - b.pose.y) < 0.15
    assert digest(analyze(back))[0].startswith("  warning: the log's time goes back")
    assert not any("warning" in line for line in digest(analyze(clean)))
