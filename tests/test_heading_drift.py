"""The drift hypotheses of the association (mapping.heading_drift): each branch maps the
scans at its own poses, a drift that is there is adopted, none is adopted where there is
none, and the test's statistic does not trust the scale of the tempered ratios."""

from __future__ import annotations

import math
from functools import cache

import numpy as np
import pytest
from ir_drive import MOUNTS, drifted, ir_scans, truth_path

from mapping.association import AssociationConfig, SampleAssociation
from mapping.beam_model import BeamModel
from mapping.grid import GridConfig, OccupancyGrid
from mapping.heading_drift import Adoption, Branch, DriftBank, drifted_step, log_evalue
from mapping.ir_inverse import IrInverseModel, scan_kinds
from mapping.scan_records import ScanRecords
from mapping.se2 import compose, relative

GRID = GridConfig(resolution_m=0.1, origin_m=(-1.0, -1.0), size_m=(9.0, 9.0))
# Only the drift test runs (no loop checks): what is tested is the bank alone.
ONLY_DRIFT = dict(check_every_m=1e6, drift_sigma_per_rad=0.01)


@cache
def _drive(heading_scale: float, distance_m: float, seed: int = 3):
    poses = truth_path(distance_m)
    return poses, ir_scans(poses, seed), drifted(poses, heading_scale, scale_sigma=0.02)


def _run(heading_scale: float, distance_m: float) -> tuple[SampleAssociation, np.ndarray, list]:
    truth, scans, est = _drive(heading_scale, distance_m)
    da = SampleAssociation(MOUNTS, AssociationConfig(**ONLY_DRIFT), GRID, seed=2)
    for h, s in zip(est, scans, strict=True):
        da.step(h, s)
    return da, truth, est


def _on(grid: OccupancyGrid, like: OccupancyGrid) -> np.ndarray:
    """``grid``'s log-odds at the cell centres of ``like`` (0 outside): grids grow in
    chunks, so two maps of the same scans may differ in extent."""
    rows, cols = like.shape
    r, c = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
    x, y = like.centre_of(r, c)
    gr, gc = grid.cell_of(x, y)
    inside = grid.inside(gr, gc)
    out = np.zeros(like.shape, dtype=np.float32)
    out[inside] = grid.logodds[gr[inside], gc[inside]]
    return out


def test_a_drifted_step_turns_by_the_corrected_change():
    rel = np.array([0.1, 0.02, 0.3])
    np.testing.assert_array_equal(drifted_step(rel, 0.0), rel)
    np.testing.assert_allclose(drifted_step(rel, 0.05), [0.1, 0.02, 0.3 * 0.95])


def test_every_branch_maps_the_scans_at_its_own_poses():
    """Scans before the bank's start go in at the association's poses, later ones at the
    branch's: each branch's map equals the map built directly from those poses."""
    truth = truth_path(6.0)[:120]
    scans = ir_scans(truth, 1)
    cfg = AssociationConfig(drift_sigma_per_rad=0.02)
    model = IrInverseModel()
    rec = ScanRecords(MOUNTS)
    start = 40
    bank = None
    for i, (p, scan) in enumerate(zip(truth, scans, strict=True)):
        if i == start:
            bank = DriftBank(cfg, 0.0, 0.02, start, truth[i - 1], OccupancyGrid(GRID), 0,
                             mounts=len(MOUNTS))  # fmt: skip
        if bank is not None:
            bank.move(relative(truth[i - 1], p))
        ranges, kinds = scan_kinds(scan)
        rec.append(p.copy(), 0.05, ranges, kinds, 0.035 * i, i)
        if bank is not None:
            bank.record()
    assert bank is not None
    while bank.ref_upto < len(rec):
        bank.age(rec, len(rec), model, 1)  # one scan per call (log-odds clamp per call)
    for b in bank.branches:
        own = [truth[start - 1]]
        for i in range(start, len(truth)):
            own.append(compose(own[-1], drifted_step(relative(truth[i - 1], truth[i]), b.drift)))
        poses = np.concatenate([truth[:start], np.array(own[1:])])
        direct = OccupancyGrid(GRID)
        for i in range(len(rec)):
            model.integrate(direct, rec.beams(i, i + 1, poses[i : i + 1]))
        np.testing.assert_allclose(_on(b.ref, direct), direct.logodds, atol=1e-5)
        assert np.count_nonzero(b.ref.logodds) == np.count_nonzero(direct.logodds)
        np.testing.assert_allclose(b.pose, poses[-1])
    turned = sum(relative(truth[i - 1], truth[i])[2] for i in range(start, len(truth)))
    assert abs(turned) > 0.5  # the branches really differ (by 0.8 rad x their drift)


def test_adopting_a_branch_moves_the_records_the_cloud_and_the_snapshots():
    rec = ScanRecords(MOUNTS)
    for i in range(6):
        rec.append(
            np.array([0.1 * i, 0.0, 0.0]), 0.01, np.ones(6), np.zeros(6, np.int8), 0.1 * i, i
        )
    old = rec.poses[-1].copy()
    own = [np.array([0.1 * i, 0.01 * i, 0.02 * i]) for i in (3, 4, 5)]
    b = Branch(0.01, 1.0, own[-1].copy(), OccupancyGrid(GRID), own)
    won = Adoption(b, 3, 9.0, 8.3, 20, 100)
    offset = np.array([0.2, -0.1, 0.05])
    cloud = np.stack([old, compose(old, offset)])
    snaps = [(0, 0.0, OccupancyGrid(GRID)), (4, 0.4, OccupancyGrid(GRID))]
    moved, kept = won.rebase(rec, cloud, old, snaps, 2, 0.5)
    np.testing.assert_allclose(moved[0], b.pose, atol=1e-12)
    np.testing.assert_allclose(moved[1], compose(b.pose, offset), atol=1e-12)
    np.testing.assert_allclose(np.array(rec.poses[3:]), np.array(own))
    assert [sn[0] for sn in kept] == [0, 2]  # the snapshot at scan 4 held old poses
    assert won.next_spacing(0.01, (-3.0, -1.5, 1.5, 3.0)) == 0.005  # a winner inside
    assert Adoption(Branch(0.03, 3.0, b.pose, b.ref), 3, 9.0, 8.3, 1, 1).next_spacing(
        0.01, (-3.0, -1.5, 1.5, 3.0)) == 0.01  # fmt: skip


def test_no_branch_is_scored_before_its_map_holds_the_same_scans():
    cfg = AssociationConfig()
    empty = OccupancyGrid(GRID)
    bank = DriftBank(cfg, 0.0, 0.01, 0, np.zeros(3), empty, 0, mounts=len(MOUNTS))
    sens, ranges, kinds = MOUNTS[:2], np.array([1.0, 2.0]), np.zeros(2, dtype=np.int8)
    assert bank.score(BeamModel(cfg), empty, 5, np.zeros(3), sens, ranges, kinds, 1.0) is None
    assert bank.scans == 0


def test_a_drift_that_is_there_is_adopted_and_corrects_the_pose():
    """Turns 3 % too large (a gyro scale error of 3 %, the prior's 3 sigma here): the
    bank adopts a drift of the right sign, and the pose ends closer to the truth."""
    da, truth, est = _run(1.03, 30.0)
    drift = [r for r in da.reports if r.outcome == "drift"]
    assert drift, da.outcome_counts()
    assert da.drift_per_rad > 0.01
    r = drift[0]
    assert r.realigned_scans > 0 and "held-out evidence" in r.reason
    assert r.log_likelihood_ratio >= da.config.confirm_nats + math.log(4)
    err_in = math.hypot(est[-1].pose.x - truth[-1, 0], est[-1].pose.y - truth[-1, 1])
    err_da = math.hypot(da.pose.x - truth[-1, 0], da.pose.y - truth[-1, 1])
    th_in = abs(math.remainder(est[-1].theta_rad - truth[-1, 2], 2 * math.pi))
    th_da = abs(math.remainder(da.pose.theta - truth[-1, 2], 2 * math.pi))
    assert th_da < 0.5 * th_in and err_da < err_in


def test_no_drift_is_adopted_where_there_is_none():
    da, truth, _ = _run(1.0, 30.0)
    assert da.outcome_counts()["drift"] == 0 and da.drift_per_rad == 0.0
    assert math.hypot(da.pose.x - truth[-1, 0], da.pose.y - truth[-1, 1]) < 1e-6


def test_the_statistic_does_not_trust_the_scale_of_the_ratios():
    """Ratios of mean zero but a large spread (what correlated beams against an
    approximate map give under the null) stay far below the threshold, where Wald's sum
    of them, reflected the same way, passes it; a steady gain does pass."""
    cfg = AssociationConfig()
    rng = np.random.default_rng(5)
    wald, lam, top_wald, top = 0.0, 0.0, 0.0, 0.0
    for x in rng.normal(0.0, 0.8, 400):
        wald = max(wald + x, cfg.reject_nats)
        lam = max(lam + log_evalue(x), cfg.reject_nats)
        top_wald, top = max(top_wald, wald), max(top, lam)
    assert top_wald > cfg.confirm_nats + math.log(4) and top < 0.25 * cfg.confirm_nats
    lam = 0.0
    for x in rng.normal(0.4, 0.4, 200):
        lam = max(lam + log_evalue(x), cfg.reject_nats)
    assert lam > cfg.confirm_nats + math.log(4)


@pytest.mark.parametrize("bad", [dict(drift_sigma_per_rad=-0.1), dict(drift_steps=(0.0, 1.0))])
def test_drift_parameters_are_checked(bad):
    with pytest.raises(ValueError, match="association drift"):
        AssociationConfig(**bad)
