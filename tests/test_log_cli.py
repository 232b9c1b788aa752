"""hilnav log info / log recover on real files, through the command line."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

from mcap.reader import make_reader

from hilnav.log.writer import LogWriter
from msgs import GyroSample, Pose2D, RobotOdometry
from tests.conftest import HILNAV, ROOT, hilnav_env

T0 = 2_000_000_000


def _cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [*HILNAV, *args], capture_output=True, text=True, env=hilnav_env(), cwd=ROOT, timeout=60
    )


def _write(path: Path, seconds: int = 10) -> None:
    with LogWriter(path, metadata={"robot": "r1", "plan": "office"}, wall_clock=False) as w:
        for i in range(seconds * 100):  # gyro 100 Hz, odometry 10 Hz
            t = T0 + i * 10_000_000
            w.write("/r1/gyro", GyroSample(t, 0.0, 0.0), t)
            if i % 10 == 0:
                odo = RobotOdometry(t, Pose2D(), 0, 0, 0, 0, 12, False, True)
                w.write("/r1/odometry", odo, t)


def test_info_lists_topics_counts_rates(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    _write(path)
    proc = _cli("log", "info", str(path), "--json")
    assert proc.returncode == 0, proc.stderr
    info = json.loads(proc.stdout)
    topics = {(t["topic"], t["schema"]): t for t in info["topics"]}
    assert topics[("/r1/gyro", "hilnav.GyroSample")]["count"] == 1000
    assert abs(topics[("/r1/gyro", "hilnav.GyroSample")]["rate_hz"] - 100.0) < 1e-6
    assert abs(topics[("/r1/odometry", "hilnav.RobotOdometry")]["rate_hz"] - 10.0) < 1e-6
    assert topics[("/tf", "foxglove.FrameTransform")]["count"] == 100
    assert info["complete"] is True and abs(info["duration_s"] - 9.99) < 1e-9
    assert info["metadata"]["hilnav"]["plan"] == "office"
    table = _cli("log", "info", str(path)).stdout
    assert "/r1/gyro" in table and "hilnav.GyroSample" in table and "100.00" in table


def test_recover_a_truncated_file(tmp_path: Path) -> None:
    path, cut, out = tmp_path / "run.mcap", tmp_path / "cut.mcap", tmp_path / "fixed.mcap"
    _write(path, seconds=10)
    data = path.read_bytes()
    cut.write_bytes(data[: len(data) // 2 + 7])  # a torn record in the middle
    info = json.loads(_cli("log", "info", str(cut), "--json").stdout)
    assert info["complete"] is False
    proc = _cli("log", "recover", str(cut), str(out))
    assert proc.returncode == 0, proc.stderr
    rep = json.loads(proc.stdout.strip().splitlines()[-1])
    assert rep["input_complete"] is False and rep["lost_tail_bytes"] > 0
    with open(out, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        gyro = [m for _, c, m in reader.iter_messages(topics=["/r1/gyro"])]
    assert summary.statistics.message_count == rep["messages"]
    assert rep["per_topic"]["/r1/gyro"] == len(gyro) > 0
    # chunks are cut every second of log time: what is kept is whole seconds from the start
    assert [m.log_time for m in gyro] == [T0 + i * 10_000_000 for i in range(len(gyro))]
    assert len(gyro) % 100 == 0
    assert json.loads(_cli("log", "info", str(out), "--json").stdout)["complete"] is True


def test_bad_files_give_clear_errors(tmp_path: Path) -> None:
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"hello, not a log")
    for args in (("log", "info", str(junk)), ("log", "recover", str(junk), str(tmp_path / "o"))):
        proc = _cli(*args)
        assert proc.returncode == 2, proc.stderr
        assert "not an MCAP file" in proc.stderr and "Traceback" not in proc.stderr
    proc = _cli("log", "info", str(tmp_path / "missing.mcap"))
    assert proc.returncode == 2 and "no such log file" in proc.stderr
    path = tmp_path / "run.mcap"
    _write(path, seconds=1)
    proc = _cli("log", "recover", str(path), str(path))
    assert proc.returncode == 2 and "differ" in proc.stderr
