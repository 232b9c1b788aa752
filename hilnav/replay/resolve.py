"""What a replay runs with: the log's robot, the robot config and the pipeline class."""

from __future__ import annotations

import tomllib
from collections import Counter
from collections.abc import Callable
from pathlib import Path
from typing import Any

from hilnav.log.reader import iter_raw
from hilnav.topics import SERVICE_INPUTS, split_log_topic

PIPELINES = ("auto", "daemon", "landmark-slam")


def guess_robot(path: str | Path, meta: dict[str, str]) -> str:
    """The log's robot: the metadata's, else the robot with the most device messages."""
    if meta.get("robot"):
        return meta["robot"]
    counts: Counter = Counter()
    for r in iter_raw(path):
        robot, kind = split_log_topic(r.topic)
        if robot and kind in SERVICE_INPUTS:
            counts[robot] += 1
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


def choose_pipeline(
    src: Path, robot: str, meta: dict[str, str], name: str, source: str
) -> tuple[Callable[[Any], Any], str]:
    """The pipeline class to replay with, and the config source to report.

    "daemon": hilnav.pipeline.Pipeline; "landmark-slam": EKF-SLAM over controls and scans
    (hilnav.replay.landmark_slam); "auto": the metadata's ``pipeline`` when it names one,
    else landmark-slam for a landmark data set (its metadata names one, or the robot has
    controls or landmark scans and no odometry)."""
    if name not in PIPELINES:
        raise ValueError(f"pipeline {name!r}: choose one of {', '.join(PIPELINES)}")
    if name == "auto" and meta.get("pipeline") in PIPELINES[1:]:
        name = meta["pipeline"]  # the importer says which
    if name == "auto":
        name = "daemon"
        if meta.get("dataset"):
            name = "landmark-slam"
        else:
            kinds = {
                split_log_topic(r.topic)[1]
                for r in iter_raw(src)
                if split_log_topic(r.topic)[0] == robot
            }
            if kinds & {"control", "landmark_scan"} and "odometry" not in kinds:
                name = "landmark-slam"
    if name == "landmark-slam":
        from hilnav.replay.landmark_slam import LandmarkSlamPipeline

        return LandmarkSlamPipeline, "landmark-slam defaults (mapping.slam.service.SlamConfig)"
    from hilnav.pipeline import Pipeline

    return Pipeline, source


def message_total(path: Path) -> int | None:
    """The log's message count from its summary (None for a truncated log)."""
    from mcap.reader import make_reader

    try:
        with open(path, "rb") as f:
            s = make_reader(f).get_summary()
        return s.statistics.message_count if s and s.statistics else None
    except Exception:
        return None
