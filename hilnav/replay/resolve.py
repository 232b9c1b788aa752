"""What a replay runs with: the log's robot, the robot config and the pipeline class."""

from __future__ import annotations

import tomllib
from collections import Counter
from collections.abc import Callable
from pathlib import Path
from typing import Any

from hilnav.log.reader import topic_counts
from hilnav.topics import SERVICE_INPUTS, split_log_topic

PIPELINES = ("auto", "daemon", "landmark-slam", "velocity")


def guess_robot(path: str | Path, meta: dict[str, str]) -> str:
    """The log's robot: the metadata's (the first of ``robots`` for a multi-robot data
    set), else the robot with the most device messages."""
    if meta.get("robot"):
        return meta["robot"]
    if meta.get("robots"):
        return meta["robots"].split(",")[0]
    counts: Counter = Counter()
    for topic, n in topic_counts(path).items():
        robot, kind = split_log_topic(topic)
        if robot and kind in SERVICE_INPUTS:
            counts[robot] += n
    if not counts:
        raise ValueError("no device messages (odometry, gyro, gps, ir) in this log")
    return sorted(counts.items(), key=lambda kv: (-kv[1], kv[0]))[0][0]


def resolve_config(config_path: str | None, meta: dict[str, str]) -> tuple[Any, str]:
    """The robot config: --config, else the TOML text or file recorded in the log, else the
    embedded defaults. Returns (config, where it came from)."""
    from hilnav.config import load_config

    if config_path:
        return load_config(config_path), config_path
    text = meta.get("config_toml")
    if text:
        from hilnav.config import parse_config

        return parse_config(tomllib.loads(text), source="log metadata"), "log metadata"
    recorded = meta.get("config", "")
    if recorded and not recorded.startswith("<") and Path(recorded).is_file():
        return load_config(recorded), recorded
    return load_config(None), "<defaults>"


def _kinds(src: Path) -> dict[str, set[str]]:
    """Robot -> the topic names it has in the log (from the summary when it has one)."""
    out: dict[str, set[str]] = {}
    for topic in topic_counts(src):
        robot, kind = split_log_topic(topic)
        if robot:
            out.setdefault(robot, set()).add(kind)
    return out


def choose_pipeline(
    src: Path, robot: str, meta: dict[str, str], name: str, source: str
) -> tuple[Callable[[Any], Any], str]:
    """The pipeline class to replay with, and the config source to report.

    "daemon": hilnav.pipeline.Pipeline; "landmark-slam": EKF-SLAM over controls and scans
    (hilnav.replay.landmark_slam); "velocity": every robot with velocity odometry, each
    through hilnav.replay.velocity_robot, together (hilnav.replay.multi_robot); "auto":
    velocity for an MRCLAM log (its metadata says so, or the robot has velocity odometry
    and no Pioneer odometry), landmark-slam for another data set or a robot with controls
    or landmark scans and no odometry, else daemon. The metadata's ``pipeline``, when it names one, comes first."""
    if name not in PIPELINES:
        raise ValueError(f"pipeline {name!r}: choose one of {', '.join(PIPELINES)}")
    kinds: dict[str, set[str]] | None = None
    if name == "auto" and meta.get("pipeline") in PIPELINES[1:]:
        name = meta["pipeline"]  # the importer says which
    if name == "auto":
        name = "daemon"
        dataset = meta.get("dataset")
        if dataset == "mrclam":
            name = "velocity"
        elif dataset:
            name = "landmark-slam"
        else:
            kinds = _kinds(src)
            mine = kinds.get(robot, set())
            if "velocity" in mine and "odometry" not in mine:
                name = "velocity"
            elif mine & {"control", "landmark_scan"} and "odometry" not in mine:
                name = "landmark-slam"
    if name == "landmark-slam":
        from hilnav.replay.landmark_slam import LandmarkSlamPipeline

        return LandmarkSlamPipeline, "landmark-slam defaults (mapping.slam.service.SlamConfig)"
    if name == "velocity":
        return _velocity_factory(src, meta, kinds), "velocity-robot services (no config)"
    from hilnav.pipeline import Pipeline

    return Pipeline, source


def _velocity_factory(
    src: Path, meta: dict[str, str], kinds: dict[str, set[str]] | None
) -> Callable[[Any], Any]:
    """All the log's velocity-odometry robots (metadata ``robots``, else those with a
    ``velocity`` topic), each from its ``initial_pose.<robot>``."""
    from hilnav.replay.multi_robot import MultiRobotPipeline
    from hilnav.replay.velocity_robot import VelocityRobotPipeline, initial_poses

    robots = [r for r in meta.get("robots", "").split(",") if r]
    if not robots:
        kinds = kinds if kinds is not None else _kinds(src)
        robots = sorted(r for r, k in kinds.items() if "velocity" in k)
    if not robots:
        raise ValueError("no robot with velocity odometry (/<robot>/velocity) in this log")
    inits = initial_poses(meta)

    def factory(config: Any) -> MultiRobotPipeline:
        return MultiRobotPipeline(robots, lambda r: VelocityRobotPipeline(r, inits.get(r)))

    return factory


def message_total(path: Path) -> int | None:
    """The log's message count from its summary (None for a truncated log)."""
    from mcap.reader import make_reader

    try:
        with open(path, "rb") as f:
            s = make_reader(f).get_summary()
        return s.statistics.message_count if s and s.statistics else None
    except Exception:
        return None
