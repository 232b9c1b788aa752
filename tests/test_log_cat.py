"""`hilnav log cat` (one line per message) and `hilnav log info` answered from the MCAP
summary: the same figures as the full scan without reading the messages, and the scan
for a truncated file."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest

import msgs
from hilnav.log import info as info_mod
from hilnav.log.info import log_info
from hilnav.log.writer import LogWriter
from msgs import GyroSample, Pose2D, PoseEstimate, RobotOdometry
from tests.conftest import HILNAV, ROOT, hilnav_env

T0 = 5_000_000_000
MS = 1_000_000


def _cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [*HILNAV, *args], capture_output=True, text=True, env=hilnav_env(), cwd=ROOT, timeout=60
    )


def _write(path: Path) -> int:
    """Many small chunks, and log times out of order across them; the record count."""
    with LogWriter(path, flush_every_s=0.1, wall_clock=False, metadata={"robot": "r1"}) as w:
        late_odo = RobotOdometry(T0 + 2000 * MS, Pose2D(), 0, 0, 0, 0, 12, False, True)
        w.write("/r1/odometry", late_odo, T0 + 2000 * MS)  # in the first chunk, the latest
        for i in range(100):
            t = T0 + i * 10 * MS
            w.write("/r1/gyro", GyroSample(t, 0.01, 0.001 * i), t)
            if i % 10 == 5:
                w.write("/r1/pose", PoseEstimate(t, Pose2D(0.1 * i, 0, 0), (0.0,) * 9), t)
        early = PoseEstimate(T0 - 500 * MS, Pose2D(), (0.0,) * 9)
        w.write("/r1/pose", early, T0 - 500 * MS)  # in the last chunk, the earliest
        w.write("/r1/odometry", late_odo, T0 + 3 * MS)
        return w.messages_written


def _figures(d: dict) -> dict:
    """An info dict without what only the scan knows (payload bytes) and its source."""
    out = {k: v for k, v in d.items() if k != "source"}
    out["topics"] = [{k: v for k, v in t.items() if k != "bytes"} for t in d["topics"]]
    return out


def test_info_comes_from_the_summary_with_the_figures_of_the_scan(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "run.mcap"
    n = _write(path)
    scanned = log_info(path, scan=True).as_dict()
    assert scanned["source"] == "scan" and scanned["messages"] == n

    def no_scan(*args, **kwargs):
        raise AssertionError("a finished file must not be scanned")

    monkeypatch.setattr(info_mod, "iter_raw", no_scan)
    quick = log_info(path).as_dict()
    assert quick["source"] == "summary"
    assert _figures(quick) == _figures(scanned)
    pose = next(t for t in quick["topics"] if t["topic"] == "/r1/pose")
    assert pose["first_ns"] == T0 - 500 * MS and pose["count"] == 11  # the late chunk's
    odo = next(t for t in quick["topics"] if t["topic"] == "/r1/odometry")
    assert (odo["first_ns"], odo["last_ns"]) == (T0 + 3 * MS, T0 + 2000 * MS)
    assert quick["metadata"]["hilnav"]["robot"] == "r1" and quick["complete"] is True


def test_info_of_a_truncated_file_scans_it(tmp_path: Path) -> None:
    path, cut = tmp_path / "run.mcap", tmp_path / "cut.mcap"
    _write(path)
    data = path.read_bytes()
    cut.write_bytes(data[: len(data) // 3])
    proc = _cli("log", "info", str(cut), "--json")
    assert proc.returncode == 0, proc.stderr
    d = json.loads(proc.stdout)
    assert d["source"] == "scan" and d["complete"] is False
    assert 0 < d["messages"] < log_info(path).messages
    assert json.loads(_cli("log", "info", str(path), "--json").stdout)["source"] == "summary"


def test_cat_prints_one_line_per_message(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    n = _write(path)
    proc = _cli("log", "cat", str(path))
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    assert len(lines) == n  # views included
    times = [int(line.split(" ", 1)[0]) for line in lines]
    assert times == sorted(times)  # log-time order
    first = lines[0].split(" ", 3)
    assert first[1:3] == ["/r1/pose", "[hilnav.PoseEstimate]"]
    assert json.loads(first[3]) == msgs.to_dict(PoseEstimate(T0 - 500 * MS, Pose2D(), (0.0,) * 9))


def test_cat_json_and_topics(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    _write(path)
    proc = _cli("log", "cat", str(path), "--json", "--topics", "/r1/gyro", "/r1/fox/*")
    assert proc.returncode == 0, proc.stderr
    rows = [json.loads(line) for line in proc.stdout.splitlines()]
    assert {r["topic"] for r in rows} == {"/r1/gyro", "/r1/fox/pose"}
    gyro = [r for r in rows if r["topic"] == "/r1/gyro"]
    assert len(gyro) == 100 and gyro[0]["schema"] == "hilnav.GyroSample"
    assert gyro[0]["log_time_ns"] == gyro[0]["publish_time_ns"] == T0
    assert msgs.decode(GyroSample, json.dumps(gyro[-1]["message"])).angle_rad == pytest.approx(
        0.099
    )
    assert all(r["schema"] == "foxglove.PoseInFrame" for r in rows if r["topic"] != "/r1/gyro")
