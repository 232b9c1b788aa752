"""The MCAP log of a real daemon run (`hilnav run` on the emulated devices): SIGKILL mid-run,
`hilnav log recover`, then replay twice (and from the raw bytes) and analyze."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import time
from pathlib import Path

import pytest
from mcap.reader import make_reader

from hilnav.bus import free_tcp_port
from tests.conftest import HILNAV, ROOT, hilnav_env


def _cli(*args: str, timeout: float = 120) -> dict:
    proc = subprocess.run(
        [*HILNAV, *args], capture_output=True, text=True, env=hilnav_env(), cwd=ROOT,
        timeout=timeout,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout.strip().splitlines()[-1])


@pytest.fixture(scope="module")
def killed_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, int]:
    tmp = tmp_path_factory.mktemp("killed")
    cfg = tmp / "r1.toml"
    cfg.write_text(
        f'name = "r1"\n[zenoh]\nlisten = ["tcp/127.0.0.1:{free_tcp_port()}"]\n'
        "[services.mapping]\npublish_every_s = 1.0\n[simulation]\nseed = 5\n"
    )
    log = tmp / "run.mcap"
    # its own session: the daemon and its fake-devices child are killed together
    proc = subprocess.Popen(
        [*HILNAV, "run", "--config", str(cfg), "--log", str(log), "--quiet"],
        stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, env=hilnav_env(),
        cwd=ROOT, start_new_session=True,
    )  # fmt: skip
    try:
        assert proc.stdout is not None
        assert " up" in proc.stdout.readline()
        time.sleep(4.0)
        killed_ns = time.time_ns()
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait(timeout=10)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait(timeout=10)
        if proc.stdout is not None:
            proc.stdout.close()
    fixed = tmp / "fixed.mcap"
    return log, fixed, killed_ns


def test_recover_after_sigkill_loses_at_most_about_a_second(killed_run) -> None:
    log, fixed, killed_ns = killed_run
    assert _cli("log", "info", str(log), "--json")["complete"] is False
    rep = _cli("log", "recover", str(log), str(fixed))
    assert rep["input_complete"] is False and rep["messages"] > 500
    with open(fixed, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        topics = {c.topic for c in summary.channels.values()}
        last_ns = max(m.log_time for _, _, m in reader.iter_messages())
    assert summary.statistics.message_count == rep["messages"]
    assert {"/r1/odometry", "/r1/gyro", "/r1/pose", "/r1/raw/arcos"} <= topics
    lost_s = (killed_ns - last_ns) / 1e9
    assert 0.0 <= lost_s < 1.3, f"lost {lost_s:.2f} s"


def test_replay_of_the_recovered_log_is_deterministic(killed_run) -> None:
    log, fixed, _ = killed_run
    if not fixed.exists():
        _cli("log", "recover", str(log), str(fixed))
    outs = {}
    for name, extra in (("a", ()), ("b", ()), ("ra", ("--from-raw",)), ("rb", ("--from-raw",))):
        out = fixed.with_name(f"replay-{name}.mcap")
        outs[name] = (out, _cli("replay", str(fixed), "--out", str(out), *extra))
    assert outs["a"][0].read_bytes() == outs["b"][0].read_bytes()
    assert outs["ra"][0].read_bytes() == outs["rb"][0].read_bytes()
    rep, raw = outs["a"][1], outs["ra"][1]
    assert rep["outputs"]["pose"] > 0 and rep["pipeline_errors"] == 0
    # the raw bytes decode again into as many device messages as the drivers made live
    for dev in ("gyro", "ir", "gps"):
        assert raw["decoded_from_raw"][dev] == rep["fed"][dev], dev
    assert abs(raw["decoded_from_raw"]["odometry"] - rep["fed"]["odometry"]) <= 1
    summary = _cli(
        "analyze", str(outs["a"][0]), "--out", str(fixed.parent / "an"), "--no-plots", "--json"
    )
    r1 = summary["robots"]["r1"]
    assert r1["reference"] == "truth" and "pose" in r1["paths"]
    assert (
        summary["metadata"]["plan"] == "office" and summary["metadata"]["replay_of"] == "fixed.mcap"
    )
