"""Sample-based data association (ir-grid-mapping eq. 7-8) on a simulated drive in the room.

A deliberately drifted run (the heading's turns scaled by 5 %, like a gyro scale error)
must come out with a better map and pose; an undrifted run must come out unharmed.
"""

import math
from functools import cache

import numpy as np
import pytest
from ir_drive import MOUNTS, drifted, ir_scans, truth_path

from fakes.world import load
from mapping.association import AssociationConfig, SampleAssociation
from mapping.grid import GridConfig, OccupancyGrid
from mapping.ir_inverse import IrInverseModel, beams_from_scan, scan_kinds
from mapping.quality import compare
from mapping.scan_records import ScanRecords
from msgs import HeadingEstimate, IrScan, Pose2D

GRID = GridConfig(resolution_m=0.1, origin_m=(-1.0, -1.0), size_m=(9.0, 9.0))
PLAN = load("paper_room")


@cache
def _drive(heading_scale: float, seed: int = 1, distance_m: float = 22.0):
    poses = truth_path(distance_m)
    return poses, ir_scans(poses, seed), drifted(poses, heading_scale)


def _plain_map(estimates, scans) -> OccupancyGrid:
    grid = OccupancyGrid(GRID)
    model = IrInverseModel()
    for h, s in zip(estimates, scans, strict=True):
        model.integrate(grid, beams_from_scan(h.pose, math.sqrt(h.variance_rad2), s, MOUNTS))
    return grid


def _with_da(estimates, scans, seed=1) -> SampleAssociation:
    da = SampleAssociation(MOUNTS, AssociationConfig(), GRID, seed=seed)
    for h, s in zip(estimates, scans, strict=True):
        da.step(h, s)
    return da


def _pos_err(pose: Pose2D, truth: np.ndarray) -> float:
    return math.hypot(pose.x - truth[0], pose.y - truth[1])


def test_association_improves_a_drifted_run():
    truth, scans, est = _drive(1.05)
    plain = compare(_plain_map(est, scans), PLAN).match_ratio
    da = _with_da(est, scans)
    with_da = compare(da.grid, PLAN).match_ratio
    assert _pos_err(est[-1].pose, truth[-1]) > 0.5  # the drift is real
    assert with_da > plain + 0.01
    assert _pos_err(da.pose, truth[-1]) < 0.75 * _pos_err(est[-1].pose, truth[-1])
    counts = da.outcome_counts()
    assert counts["accepted"] >= 1
    accepted = [r for r in da.reports if r.outcome == "accepted"]
    cfg = da.config
    assert all(r.realigned_scans > 0 and r.log_likelihood_ratio >= cfg.lr_min for r in accepted)
    assert all(r.ess_fraction <= cfg.ess_max and "held-out LR" in r.reason for r in accepted)
    # The corrected trajectory is closer to the truth than the drifted one, on average.
    traj = da.trajectory
    drift = np.array([[h.pose.x, h.pose.y] for h in est])
    assert np.mean(np.hypot(*(traj[:, :2] - truth[:, :2]).T)) < np.mean(
        np.hypot(*(drift - truth[:, :2]).T)
    )


def test_association_leaves_an_undrifted_run_unharmed():
    truth, scans, est = _drive(1.0)
    plain = compare(_plain_map(est, scans), PLAN).match_ratio
    da = _with_da(est, scans)
    assert compare(da.grid, PLAN).match_ratio >= plain - 0.005
    assert _pos_err(da.pose, truth[-1]) < 0.05
    assert len(da.reports) >= 5  # the loop was closed and checked...
    for r in da.reports:  # ...and every kept branch says why
        assert r.outcome in ("accepted", "unconfirmed", "confirmed", "weak", "worse")
        if r.outcome != "accepted":
            assert r.reason and r.realigned_scans == 0


def test_beam_model_prefers_the_true_pose():
    """Eq. 7-8 against the map built from true poses: the truth outscores displaced poses."""
    truth, scans, est = _drive(1.0)
    da = _with_da(est[:300], scans[:300])
    da._ref = da.grid.copy()  # match against everything seen so far
    k = 299
    sens = np.array(MOUNTS)
    ranges, kinds = scan_kinds(scans[k])
    keep = kinds >= 0
    p = truth[k]
    cands = np.array([p, p + [0.3, 0, 0], p + [0, 0.3, 0], p + [0, 0, 0.2], p - [0.3, 0.3, 0.2]])
    ll = da.log_likelihood(cands, sens[keep], ranges[keep], kinds[keep])
    assert np.argmax(ll) == 0 and np.all(np.isfinite(ll))


def test_configuration_and_input_errors_are_clear():
    with pytest.raises(ValueError, match="a_hit"):
        AssociationConfig(a_hit=0.5, a_rand=0.2, a_max=0.05)
    with pytest.raises(ValueError, match="min_loop_m"):
        AssociationConfig(min_loop_m=1.0, ref_lag_m=3.0)
    with pytest.raises(ValueError, match="mounts"):
        SampleAssociation(np.zeros((6, 2)))
    da = SampleAssociation(MOUNTS, grid_config=GRID)
    h = HeadingEstimate(0, 0.0, 0.0, Pose2D(1.5, 1.5, 0.0))
    with pytest.raises(ValueError, match="mount per channel"):
        da.step(h, IrScan(0, 0, 0, (2.0,), ("ok",), (2.0,)))
    # A non-finite pose is counted and skipped, not a crash.
    bad = HeadingEstimate(1, math.nan, 0.0, Pose2D(math.nan, 0.0, 0.0))
    assert da.step(bad, IrScan(1, 0, 1, (2.0,) * 6, ("ok",) * 6, (2.0,) * 6)) is None
    assert da.skipped_readings == 6


def test_a_window_holds_about_window_beams_beams_whatever_the_layout() -> None:
    """The window of eq. 7 is counted in beams (AssociationConfig.window_scans): 8 scans
    of the default six sensors, 12 of four, 6 of eight; the records give that many."""
    cfg = AssociationConfig()
    assert [cfg.window_scans(k) for k in (1, 3, 4, 5, 6, 7, 8)] == [48, 16, 12, 10, 8, 7, 6]
    assert AssociationConfig(window_beams=5).window_scans(8) == 2  # never fewer than two
    with pytest.raises(ValueError, match="window_beams"):
        AssociationConfig(window_beams=0)
    for k in (4, 6, 8):
        mounts = np.column_stack([np.zeros(k), np.zeros(k), np.linspace(-1.5, 1.5, k)])
        rec = ScanRecords(mounts)
        for i in range(40):  # 2 m in 5 cm steps: more scans than a window takes
            pose = np.array([0.05 * i, 0.0, 0.0])
            rec.append(pose, 0.01, np.full(k, 2.0), np.zeros(k, dtype=np.int8), 0.05 * i, i)
        sens, ranges, kinds = rec.window(np.array([1.95, 0.0, 0.0]), 1.95, cfg)
        assert len(ranges) == cfg.window_scans(k) * k == 48


def test_a_scan_beyond_the_grid_limit_is_refused_and_mapping_resumes_back_inside() -> None:
    """A robot that drives past what ``max_cells`` lets the grid hold: those scans are
    refused and counted before anything records them (a record the maps could not take
    would stop every later insertion), nothing raises, and the scans are mapped again
    once it is back."""
    da = SampleAssociation(MOUNTS, grid_config=GridConfig(max_cells=800 * 800))
    xs = [0.1 * k for k in range(400)]  # 40 m east and back, in 10 cm steps
    for k, x in enumerate(xs + xs[::-1]):
        h = HeadingEstimate(k * 10**8, 0.0, 1e-4, Pose2D(x, 0.0, 0.0))
        da.step(h, IrScan(k * 10**8, 0, k, (2.0,) * 6, ("ok",) * 6, (2.0,) * 6))
    assert 0 < da.refused_scans < 800
    tr = da.trajectory
    assert len(tr) + da.refused_scans == 800
    assert 10.0 < tr[:, 0].max() < 40.0 and tr[-1, 0] == pytest.approx(0.0)  # mapped again
    rows, cols = da.grid.shape
    assert rows * cols <= 800 * 800


def test_grid_fits_says_whether_it_may_grow_without_growing() -> None:
    g = OccupancyGrid(GridConfig(size_m=(10.0, 10.0), max_cells=400 * 400))
    assert g.fits(-4.0, -4.0, 4.0, 4.0) and g.fits(-4.0, -4.0, 12.0, 4.0)
    assert not g.fits(-4.0, -4.0, 40.0, 4.0) and not g.fits(0.0, 0.0, math.inf, 1.0)
    assert g.shape == (200, 200)  # nothing grew
    assert g.ensure(-4.0, -4.0, 12.0, 4.0)
    with pytest.raises(ValueError, match="max_cells"):
        g.ensure(-4.0, -4.0, 40.0, 4.0)


def test_a_graph_map_the_grid_cannot_hold_keeps_the_associations_map() -> None:
    """finish(): if the map at the pose graph's poses would need more than ``max_cells``
    (here a limit set below the map already drawn), the association's map stays and
    the outcome says why; nothing raises."""
    truth, scans, est = _drive(1.05)
    da = _with_da(est, scans)
    assert da._graph is not None and da._graph.loops  # the graph has something to solve
    before = da.grid.logodds.copy()
    da._grid_config = GridConfig(resolution_m=0.1, origin_m=(-1.0, -1.0), size_m=(9.0, 9.0),
                                 max_cells=90 * 90)  # fmt: skip
    assert da.finish() is da.grid
    assert da.graph_outcome.startswith("kept the association's map (the graph's map: grid")
    np.testing.assert_array_equal(da.grid.logodds, before)


def test_scan_box_holds_every_cone_a_scan_may_draw() -> None:
    """Whenever the grid says it can hold a scan's box (IrInverseModel.scan_box), the
    widest scan there (every beam clear to the maximum range, the widest cone) goes in
    without raising; poses swept up to and past the limit."""
    model = IrInverseModel()
    n = len(MOUNTS)
    widest = IrScan(0, 0, 0, (math.nan,) * n, ("too_far",) * n, (0.0,) * n)
    taken = refused = 0
    for k in range(60):
        g = OccupancyGrid(
            GridConfig(origin_m=(-10.0, -10.0), size_m=(20.0, 20.0), max_cells=400 * 440)
        )
        pose = np.array([3.0 + 0.05 * k, 0.5, 0.3 * k])
        if g.fits(*model.scan_box(pose, MOUNTS, g.resolution)):
            model.integrate(g, beams_from_scan(Pose2D(*pose), 1.0, widest, MOUNTS))
            taken += 1
        else:
            refused += 1
    assert taken and refused
