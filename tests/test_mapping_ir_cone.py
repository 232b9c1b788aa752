"""The fast IR cone update (mapping.ir_cone, grid.add) against the reference lattice
(mapping.ir_reference): the same cells, the same float64 increments, the same grid bits."""

import math

import numpy as np
import pytest

from mapping.grid import GridConfig, OccupancyGrid
from mapping.ir_cone import _wrap_abs
from mapping.ir_inverse import (
    KIND_CLEAR,
    KIND_HIT,
    KIND_SKIP,
    Beams,
    InverseModelConfig,
    IrInverseModel,
    beams_from_scan,
)
from mapping.ir_reference import reference_updates
from msgs import IrScan, Pose2D
from numerics.angles import TWO_PI, wrap_angles


def _random_beams(rng: np.random.Generator, n: int, spread_m: float = 3.0) -> Beams:
    """Beams anywhere, pointing anywhere (angles far outside (-pi, pi] too), with every
    kind of reading: hits near and far, clears, NaN and out-of-range ranges."""
    kind = rng.choice([KIND_HIT, KIND_HIT, KIND_HIT, KIND_CLEAR, KIND_SKIP], n).astype(np.int8)
    rng_m = rng.uniform(0.05, 6.5, n)
    rng_m[rng.random(n) < 0.05] = np.nan
    sigma = np.where(rng.random(n) < 0.3, 0.0, rng.uniform(0.0, 0.2, n))
    angle = rng.uniform(-3 * math.pi, 3 * math.pi, n)
    angle[rng.random(n) < 0.1] = rng.choice([0.0, math.pi / 2, -math.pi, math.pi])
    return Beams(
        rng.uniform(-spread_m, spread_m, n),
        rng.uniform(-spread_m, spread_m, n),
        angle,
        np.where(kind == KIND_HIT, rng_m, np.nan),
        kind,
        sigma,
    )


def _same(a: tuple[np.ndarray, np.ndarray], b: tuple[np.ndarray, np.ndarray]) -> None:
    assert a[0].dtype == b[0].dtype == np.int64
    np.testing.assert_array_equal(a[0], b[0])
    np.testing.assert_array_equal(a[1].view(np.uint64), b[1].view(np.uint64))  # bit for bit


@pytest.mark.parametrize("res", [0.05, 0.1, 0.033])
def test_updates_equal_the_reference_bit_for_bit_on_random_beams(res):
    rng = np.random.default_rng(int(res * 1000))
    for n in (1, 2, 6, 17):
        for heading in (True, False):
            cfg = InverseModelConfig(use_heading_uncertainty=heading)
            model = IrInverseModel(cfg)
            beams = _random_beams(rng, n)
            g_fast = OccupancyGrid(GridConfig(resolution_m=res))
            g_ref = OccupancyGrid(GridConfig(resolution_m=res))
            _same(model.updates(g_fast, beams), reference_updates(model, g_ref, beams))
            assert g_fast.shape == g_ref.shape and g_fast.origin == g_ref.origin


def test_updates_equal_the_reference_for_other_model_parameters():
    rng = np.random.default_rng(7)
    cfg = InverseModelConfig(
        p_free=0.2,
        p_occupied=0.9,
        hit_halfwidth_m=0.2,
        max_range_m=3.0,
        min_half_angle_rad=0.05,
        max_half_angle_rad=0.6,
    )
    model = IrInverseModel(cfg)
    beams = _random_beams(rng, 12)
    g1, g2 = OccupancyGrid(), OccupancyGrid()
    _same(model.updates(g1, beams), reference_updates(model, g2, beams))


def test_a_split_batch_gives_the_same_updates():
    rng = np.random.default_rng(3)
    beams = _random_beams(rng, 10)
    small = IrInverseModel(max_samples_per_call=3000)  # forces several parts
    g1, g2 = OccupancyGrid(), OccupancyGrid()
    _same(small.updates(g1, beams), reference_updates(small, g2, beams))


def _reference_add(grid: OccupancyGrid, idx: np.ndarray, dl: np.ndarray) -> None:
    """The grid update as first written: np.unique, a float64 sum per cell, clamp."""
    touched, inv = np.unique(idx, return_inverse=True)
    total = np.bincount(inv, weights=dl)
    flat = grid.logodds.reshape(-1)
    c = grid.config
    flat[touched] = np.clip(flat[touched] + total, c.l_min, c.l_max).astype(np.float32)


def test_a_mapping_run_gives_the_reference_grid_bit_for_bit():
    """Scans along a path (six sensors, growing heading sigma), integrated scan by scan
    by the fast path and by the reference updates + reference add: identical grids."""
    rng = np.random.default_rng(11)
    mounts = np.array([[0.2, 0.06, 0.17], [0.2, -0.06, -0.17], [0.16, 0.14, 0.79],
                       [0.16, -0.14, -0.79], [0.02, 0.19, 1.57], [0.02, -0.19, -1.57]])  # fmt: skip
    model = IrInverseModel()
    g_fast = OccupancyGrid(GridConfig(size_m=(4.0, 4.0), origin_m=(-2.0, -2.0)))
    g_ref = OccupancyGrid(GridConfig(size_m=(4.0, 4.0), origin_m=(-2.0, -2.0)))
    x = y = th = 0.0
    for i in range(60):
        x, y, th = x + 0.1 * math.cos(th), y + 0.1 * math.sin(th), th + rng.normal(0, 0.2)
        status = tuple(rng.choice(["ok", "ok", "ok", "no_return", "too_near"], 6))
        ranges = tuple(float(r) for r in rng.uniform(0.3, 5.5, 6))
        scan = IrScan(i, 0, i, ranges, status, (2.0,) * 6)  # type: ignore[arg-type]
        beams = beams_from_scan(Pose2D(x, y, th), 0.005 * i, scan, mounts)
        model.integrate(g_fast, beams)
        _reference_add(g_ref, *reference_updates(model, g_ref, beams))
    assert g_fast.origin == g_ref.origin
    np.testing.assert_array_equal(g_fast.logodds.view(np.uint32), g_ref.logodds.view(np.uint32))
    assert np.any(g_fast.logodds == g_fast.config.l_min)  # the clamp was reached


@pytest.mark.parametrize("spread", [50, 10**6])  # a window of cells, and np.unique
def test_grid_add_sums_repeats_in_order_and_clamps_like_the_reference(spread):
    rng = np.random.default_rng(spread)
    g1 = OccupancyGrid(GridConfig(size_m=(60.0, 60.0), resolution_m=0.05))  # 1.44 M cells
    g2 = g1.copy()
    for _ in range(5):
        idx = rng.integers(0, spread, 3000) + rng.integers(0, g1.logodds.size - spread)
        dl = rng.normal(0.0, 2.0, 3000)
        assert g1.add(idx, dl) == 3000
        _reference_add(g2, idx, dl)
    np.testing.assert_array_equal(g1.logodds.view(np.uint32), g2.logodds.view(np.uint32))
    assert g1.add(np.zeros(0, dtype=np.int64), np.zeros(0)) == 0


def test_exact_wrap_equals_numpy_mod_wrap():
    rng = np.random.default_rng(5)
    edges = [-0.0, 0.0, 1e-300, -1e-17, 1e300, -1e300, math.pi, -math.pi]
    for c in np.arange(-4, 5) * TWO_PI - math.pi:  # where a + pi crosses a multiple of 2 pi
        up = down = c
        for _ in range(4):
            edges += [up, down]
            up, down = np.nextafter(up, np.inf), np.nextafter(down, -np.inf)
    for a in (rng.uniform(-30, 30, 20000), rng.uniform(-7, 7, 20000), np.array(edges)):
        np.testing.assert_array_equal(_wrap_abs(a), np.abs(wrap_angles(a)))


def _scan_beams(rng: np.random.Generator, n_scans: int) -> list[Beams]:
    return [_random_beams(rng, 6, spread_m=1.5) for _ in range(n_scans)]


def test_reused_updates_give_the_same_second_grid_and_are_forgotten_once_used():
    """A scan into grid A, later into grid B (the association's map and reference map):
    with the memo B is bit for bit what B is without it, and the memo empties as B
    catches up."""
    rng = np.random.default_rng(21)
    scans = _scan_beams(rng, 12)
    plain, memo = IrInverseModel(), IrInverseModel(reuse_cells=10**7)
    big = GridConfig(origin_m=(-10.0, -10.0), size_m=(20.0, 20.0))  # no growth: one origin
    grids = {m: (OccupancyGrid(big), OccupancyGrid(big)) for m in ("plain", "memo")}
    upto = 0  # B takes the scans three behind A, one or two at a time
    for i, beams in enumerate(scans):
        stop = min(i - 2, upto + 1 + i % 2)
        for name, model in (("plain", plain), ("memo", memo)):
            a, b = grids[name]
            model.integrate(a, beams)
            if stop > upto:
                model.integrate(b, Beams.concat(scans[upto:stop]))
        upto = max(upto, stop)
    for x, y in zip(grids["plain"], grids["memo"], strict=True):
        assert x.origin == y.origin
        np.testing.assert_array_equal(x.logodds.view(np.uint32), y.logodds.view(np.uint32))
    assert memo._memo is not None and memo._memo.hits == 6 * upto  # each scan B took
    assert len(memo._memo._kept) == 6 * (len(scans) - upto)  # only the scans B has not


def test_reuse_needs_the_same_origin_handles_another_width_and_keeps_its_bound():
    rng = np.random.default_rng(22)
    beams = _random_beams(rng, 6, spread_m=1.0)
    model = IrInverseModel(reuse_cells=10**7)
    first = OccupancyGrid(GridConfig(origin_m=(-5.0, -5.0), size_m=(10.0, 10.0)))
    want = model.updates(first, beams)
    wider = OccupancyGrid(GridConfig(origin_m=(-5.0, -5.0), size_m=(14.0, 10.0)))
    got = model.updates(wider, beams)  # same origin, more columns: reused, re-indexed
    assert model._memo is not None and model._memo.hits == 6
    rows, cols = np.divmod(want[0], first.shape[1])
    _same(got, (rows * wider.shape[1] + cols, want[1]))
    moved = OccupancyGrid(GridConfig(origin_m=(-5.05, -5.0), size_m=(10.0, 10.0)))
    _same(model.updates(moved, beams), reference_updates(model, moved.copy(), beams))
    assert model._memo.hits == 6  # another origin: computed again
    tiny = IrInverseModel(reuse_cells=10)
    tiny.updates(OccupancyGrid(), beams)
    assert tiny._memo is not None and tiny._memo.cells <= 10
