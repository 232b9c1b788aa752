"""The motion filter before the IR grid (mapping.motion_filter) and the mapping service
that uses it: which scans go into the grid."""

from __future__ import annotations

import math

import pytest

from hilnav.config import parse_config
from hilnav.services import MappingAdapter, motion_filter_config
from mapping.motion_filter import MotionFilter, MotionFilterConfig
from msgs import HeadingEstimate, IrScan, Pose2D

MS = 1_000_000


def test_travel_turn_time_and_the_first_scan() -> None:
    f = MotionFilter(MotionFilterConfig(min_travel_m=0.05, min_turn_rad=math.radians(2),
                                        max_interval_s=1.0))  # fmt: skip
    assert f.keep(Pose2D(0, 0, 0), 0)  # the first
    assert not f.keep(Pose2D(0.03, 0.0, 0.0), 50 * MS)
    assert not f.keep(Pose2D(0.049, 0.0, 0.0), 100 * MS)  # 4.9 cm since the last kept
    assert f.keep(Pose2D(0.03, 0.04, 0.0), 150 * MS)  # 5 cm: kept
    assert not f.keep(Pose2D(0.03, 0.04, math.radians(1.9)), 200 * MS)
    assert f.keep(Pose2D(0.03, 0.04, math.radians(-2.1)), 250 * MS)  # turned the other way
    # standing still: once a second, not at the scan rate
    assert not f.keep(Pose2D(0.03, 0.04, math.radians(-2.1)), 1249 * MS)
    assert f.keep(Pose2D(0.03, 0.04, math.radians(-2.1)), 1250 * MS)
    # the turn is measured across the wrap at pi
    g = MotionFilter()
    assert g.keep(Pose2D(0, 0, math.pi - 0.01), 0)
    assert not g.keep(Pose2D(0, 0, -math.pi + 0.01), MS)  # 1.1 deg, not 358.9
    assert (f.kept, f.dropped) == (4, 4)


def test_a_clock_that_goes_back_resets_and_a_pose_that_is_not_finite_is_counted() -> None:
    f = MotionFilter()
    assert f.keep(Pose2D(1.0, 1.0, 0.0), 10_000 * MS)
    assert f.keep(Pose2D(1.0, 1.0, 0.0), 5_000 * MS)  # a reset source: start again
    assert not f.keep(Pose2D(1.0, 1.0, 0.0), 5_100 * MS)
    for bad in (Pose2D(math.nan, 1.0, 0.0), Pose2D(1.0, math.inf, 0.0), Pose2D(1, 1, math.nan)):
        assert not f.keep(bad, 9_000 * MS)  # nowhere to map it
    assert not f.keep(Pose2D(1.0, 1.0, 0.0), 5_300 * MS)  # measured from the last finite
    assert (f.kept, f.dropped, f.unplaced) == (2, 2, 3)


def test_off_maps_every_scan_inf_switches_a_trigger_off_and_zero_is_refused() -> None:
    f = MotionFilter(MotionFilterConfig(enabled=False))
    assert all(f.keep(Pose2D(0, 0, 0), i * MS) for i in range(20))
    still = MotionFilter(MotionFilterConfig(max_interval_s=math.inf))
    assert still.keep(Pose2D(0, 0, 0), 0)
    assert not any(still.keep(Pose2D(0, 0, 0), i * 1000 * MS) for i in range(1, 20))
    for bad in ({"min_travel_m": 0.0}, {"min_travel_m": -0.01}, {"min_turn_rad": math.nan},
                {"max_interval_s": 0.0}):  # fmt: skip
        with pytest.raises(ValueError, match="motion filter"):
            MotionFilterConfig(**bad)


def _feed(adapter: MappingAdapter, poses: list[Pose2D], period_ms: int = 50) -> None:
    for i, p in enumerate(poses):
        t = (i + 1) * period_ms * MS
        adapter.feed("heading", HeadingEstimate(t, p.theta, 1e-6, p))
        adapter.feed("ir", IrScan(t, 1, i, (2.0,) * 6, ("ok",) * 6, (1.0,) * 6))


@pytest.mark.parametrize("association", [False, True])
def test_the_mapping_service_maps_at_a_spacing_of_travel(association: bool) -> None:
    """20 Hz scans at 0.3 m/s (1.5 cm apart) over 3 m: a scan every 5 cm goes in; then
    standing still for 5 s: one a second. The config sets the spacing; 0 maps each."""
    cfg = parse_config({"services": {"mapping": {"association": association}}})
    assert motion_filter_config(cfg) == MotionFilterConfig()
    a = MappingAdapter(cfg)
    moving = [Pose2D(0.015 * i, 0.0, 0.0) for i in range(200)]
    _feed(a, moving + [moving[-1]] * 100)
    assert a.scans == 300 and a.filter.kept + a.filter.dropped == 300
    assert a.filter.kept == 50 + 5  # every 4th scan moving (6 cm), then one a second
    if association:
        assert a.da is not None and len(a.da.trajectory) == a.filter.kept
    assert a.summary().startswith(f"300 IR scans: {a.filter.kept} mapped, ")
    every = MappingAdapter(parse_config({"services": {"mapping": {"motion_filter": False}}}))
    _feed(every, moving)
    assert every.filter.dropped == 0 and every.grid.updates > a.grid.updates > 0
    with pytest.raises(ValueError, match="min_travel_m"):
        parse_config({"services": {"mapping": {"min_travel_m": 0.0}}})
    lazy = parse_config({"services": {"mapping": {"max_interval_s": 1e9}}})
    assert motion_filter_config(lazy).max_interval_s == 1e9  # never by time


def test_a_scan_without_a_finite_pose_is_counted_not_mapped() -> None:
    """A heading estimate with a NaN pose (a filter that lost itself) must not reach the
    grid (which refuses non-finite boxes): counted, and the service goes on."""
    a = MappingAdapter(parse_config({"services": {"mapping": {"association": False}}}))
    _feed(a, [Pose2D(0.0, 0.0, 0.0), Pose2D(math.nan, 0.0, 0.0), Pose2D(0.1, 0.0, 0.0)])
    assert (a.filter.kept, a.filter.unplaced) == (2, 1) and a.grid.updates > 0
    assert "1 without a finite pose" in a.summary()


@pytest.mark.parametrize("association", [False, True])
def test_a_scan_the_grid_cannot_hold_is_refused_and_counted(association: bool) -> None:
    """A pose 1,000 km out (the grid may hold 25 M cells): the scan is refused and
    counted, nothing raises, and the scans back home are mapped."""
    a = MappingAdapter(parse_config({"services": {"mapping": {"association": association}}}))
    _feed(a, [Pose2D(0.0, 0.0, 0.0), Pose2D(1e6, 0.0, 0.0), Pose2D(0.1, 0.0, 0.0)])
    assert a.filter.kept == 3 and a.grid.updates > 0
    assert "1 refused beyond the grid's max_cells" in a.summary()
    rows, cols = a.grid.shape
    assert rows * cols < 1_000_000


@pytest.mark.parametrize("graph", [False, True])
def test_the_end_of_a_run_gives_the_final_map_once(graph: bool) -> None:
    """``finish()``: nothing before the first scan; then the final map stamped at the last
    scan, once; the summary says what the association's pose graph did (or that it is
    off); the runtime logs that map when it closes."""
    cfg = parse_config({"services": {"mapping": {"pose_graph": graph}}, "log": {"raw": False}})
    a = MappingAdapter(cfg)
    assert a.finish() == []  # no scan yet
    _feed(a, [Pose2D(0.015 * i, 0.0, 0.0) for i in range(200)])
    ((topic, final),) = a.finish()
    assert topic == "map" and final.timestamp.sec * 10**9 + final.timestamp.nsec == 200 * 50 * MS
    assert a.finish() == []  # once
    assert a.da is not None and a.summary().endswith(f"pose graph: {a.da.graph_outcome}")
    assert (a.da.graph_outcome == "off") is not graph  # a straight line: no loop, or off


def test_the_runtime_logs_the_final_map_when_it_closes(tmp_path) -> None:
    from hilnav.log.reader import read_messages
    from hilnav.pipeline import Pipeline
    from hilnav.runtime import RobotRuntime

    cfg = parse_config({"name": "r1", "log": {"raw": False},
                        "services": {"localization": {"enabled": False}}})  # fmt: skip
    # the mapping in the runtime's thread (no worker), fed headings as the service would
    rt = RobotRuntime(cfg, pipeline=lambda c, on_mapping, **kw: Pipeline(c, **kw))
    rt.open_log(tmp_path / "r1.mcap", simulated=True)
    for i in range(60):
        t = (i + 1) * 50 * MS
        p = Pose2D(0.015 * i, 0.0, 0.0)
        rt.pipeline.mapping.feed("heading", HeadingEstimate(t, 0.0, 1e-6, p))
        rt.put("ir", IrScan(t, 1, i, (2.0,) * 6, ("ok",) * 6, (1.0,) * 6), recv_ns=t)
        rt.drain()
    rt.close()
    maps = [m.msg for m in read_messages(tmp_path / "r1.mcap") if m.topic == "/r1/map"]
    assert (maps[-1].timestamp.sec, maps[-1].timestamp.nsec) == (3, 0)  # the last scan's
    assert rt.pipeline.mapping.finished and rt.stats.faults == {}
