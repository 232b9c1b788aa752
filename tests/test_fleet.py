"""``hilnav fleet``: three robot processes over loopback Zenoh; containment, and a killed
robot is dropped by the others, which carry on alone."""

from __future__ import annotations

import json
import subprocess

from conftest import HILNAV, hilnav_env

from hilnav.log.reader import read_messages
from msgs import PoseBox


def test_three_robot_fleet_contains_truth_and_drops_a_killed_robot(tmp_path):
    out = tmp_path / "logs"
    cmd = [*HILNAV, "fleet", "--robots", "3", "--scenario", "paper", "--duration", "3", "--rate", "2",
           "--kill", "r3@0.8", "--out", "logs"]  # fmt: skip
    # run from another directory than the checkout, with a relative --out
    proc = subprocess.run(
        cmd, capture_output=True, text=True, timeout=120, env=hilnav_env(), cwd=tmp_path
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    lines = proc.stdout.strip().splitlines()
    res = json.loads(lines[-1])
    assert "killed r3" in proc.stdout
    # The survivors finished every step with their boxes around the truth.
    assert res["robots"] == ["r1", "r2"]
    assert res["multi_cp_containment"] == 1.0 and res["single_cp_containment"] == 1.0
    assert res["dropped"] == {"r1": ["r3"], "r2": ["r3"]}
    for k in ("ekf_area", "single_cp_area", "multi_cp_area", "ekf_containment", "steps_per_second"):
        assert k in res
    assert res["multi_cp_area"] < res["single_cp_area"]  # the peers' boxes helped
    # One MCAP per robot; r1 logged its own boxes and the others' received over Zenoh,
    # and r3's boxes stop early (killed) while r2's go on to the end.
    assert {p.name for p in out.glob("*.mcap")} >= {"r1.mcap", "r2.mcap", "r3.mcap"}
    seen: dict[str, list[int]] = {}
    for m in read_messages(
        out / "r1.mcap", topics=["/r1/pose_box", "/r2/pose_box", "/r3/pose_box"]
    ):
        assert isinstance(m.msg, PoseBox)
        seen.setdefault(m.topic, []).append(m.msg.stamp_ns)
    end = max(seen["/r1/pose_box"])
    assert max(seen["/r2/pose_box"]) >= end - 200_000_000
    assert seen.get("/r3/pose_box") and max(seen["/r3/pose_box"]) < end - 500_000_000
