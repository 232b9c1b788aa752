"""IR inverse sensor model (ir-grid-mapping fig. 4) and its eq. 6 heading cone."""

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from mapping.grid import GridConfig, OccupancyGrid, logit
from mapping.ir_inverse import InverseModelConfig, IrInverseModel, attenuate, beams_from_scan
from msgs import IrScan, Pose2D

ONE = np.zeros((1, 3))  # one sensor at the robot's centre, looking forward


def _grid(**kw):
    return OccupancyGrid(
        GridConfig(resolution_m=0.05, origin_m=(-1.0, -2.0), size_m=(8.0, 4.0), **kw)
    )


def _scan(*readings):
    ranges = tuple(r for r, _ in readings)
    return IrScan(0, 0, 0, ranges, tuple(s for _, s in readings), tuple(2.0 for _ in readings))


def _at(grid, x, y):
    r, c = grid.cell_of(np.atleast_1d(x), np.atleast_1d(y))
    return grid.logodds[r, c]


def _one_beam(range_m, status="ok", sigma=0.0, cfg=None):
    g = _grid()
    model = IrInverseModel(cfg or InverseModelConfig())
    beams = beams_from_scan(Pose2D(0.0, 0.0, 0.0), sigma, _scan((range_m, status)), ONE)
    n = model.integrate(g, beams)
    return g, n, model.config


def test_free_before_the_hit_occupied_at_it_unknown_behind():
    g, n, cfg = _one_beam(2.0)
    free = _at(g, [0.3, 0.8, 1.3, 1.8], 0.01)
    assert n > 0
    assert free == pytest.approx([logit(cfg.p_free)] * 4)
    assert _at(g, 2.01, 0.01)[0] == pytest.approx(logit(cfg.p_occupied))
    assert np.all(_at(g, [2.3, 2.6, 3.5, 5.0], 0.01) == 0.0)  # behind the hit: untouched
    assert _at(g, -0.3, 0.01)[0] == 0.0  # behind the sensor


def test_no_return_clears_only_up_to_the_maximum_range():
    for status in ("no_return", "too_far"):
        g, _, cfg = _one_beam(math.nan, status)
        assert np.all(_at(g, [0.5, 2.5, 5.2], 0.01) == pytest.approx(logit(cfg.p_free)))
        assert np.all(_at(g, [5.7, 6.0, 6.5], 0.01) == 0.0)
        assert np.all(g.logodds <= 0.0)  # nothing marked occupied


def test_too_near_and_invalid_readings_are_skipped_and_counted():
    scan = _scan((0.7, "too_near"), (math.nan, "invalid"), (2.0, "ok"))
    mounts = np.zeros((3, 3))
    beams = beams_from_scan(Pose2D(), 0.0, scan, mounts)
    assert len(beams) == 1 and beams.skipped == 2


def test_mismatched_mounts_give_a_clear_error():
    with pytest.raises(ValueError, match="mount per channel"):
        beams_from_scan(Pose2D(), 0.0, _scan((2.0, "ok")), np.zeros((2, 3)))


def test_eq6_exponent_pulls_towards_one_half():
    p = np.array([0.3, 0.8])
    assert attenuate(p, 0.0, 0.1) == pytest.approx(p)  # on the axis: unchanged
    # At the edge of the 3-sigma cone the exponent is 2.
    assert attenuate(p, 0.1, 0.1) == pytest.approx([0.5 - 0.2**2, 0.5 + 0.3**2])
    assert attenuate(p, -0.05, 0.1) == pytest.approx([0.5 - 0.2**1.5, 0.5 + 0.3**1.5])
    assert attenuate(np.array([0.5]), 0.3, 0.1)[0] == 0.5


@given(st.floats(0.01, 0.99), st.floats(0.0, 1.0), st.floats(0.0, 1.0), st.floats(1e-3, 1.0))
def test_eq6_is_monotone_in_alpha_and_keeps_the_side(p, a1, a2, s3):
    lo, hi = sorted((a1, a2))
    near, far = attenuate(np.array([p]), lo, s3)[0], attenuate(np.array([p]), hi, s3)[0]
    assert abs(far - 0.5) <= abs(near - 0.5) + 1e-12 <= abs(p - 0.5) + 2e-12
    assert (near - 0.5) * (p - 0.5) >= 0.0


def test_heading_uncertainty_widens_the_beam_and_weakens_off_axis_cells():
    narrow, _, cfg = _one_beam(3.0, sigma=0.0)
    wide, _, _ = _one_beam(3.0, sigma=math.radians(3.0))  # 3 sigma = 9 deg
    assert (wide.logodds != 0).sum() > 3 * (narrow.logodds != 0).sum()
    # On the axis the full fig. 4 update; 5 deg off the axis (inside 9 deg) a weaker one
    # of the same sign; 15 deg off, outside the cone, none.
    assert _at(wide, 1.5, 0.01)[0] == pytest.approx(logit(cfg.p_free))
    off = _at(wide, 1.5 * math.cos(0.087), 1.5 * math.sin(0.087))[0]
    assert logit(cfg.p_free) < off < 0.0
    assert _at(wide, 1.5 * math.cos(0.26), 1.5 * math.sin(0.26))[0] == 0.0
    assert _at(narrow, 1.5 * math.cos(0.087), 1.5 * math.sin(0.087))[0] == 0.0


def test_plain_model_ignores_the_heading_sigma():
    cfg = InverseModelConfig(use_heading_uncertainty=False)
    a, _, _ = _one_beam(3.0, sigma=0.0, cfg=cfg)
    b, _, _ = _one_beam(3.0, sigma=math.radians(5.0), cfg=cfg)
    assert np.array_equal(a.logodds, b.logodds)


def test_all_beams_at_once_equal_one_by_one():
    rng = np.random.default_rng(3)
    mounts = np.column_stack([rng.uniform(-0.2, 0.2, 6), rng.uniform(-0.2, 0.2, 6),
                              rng.uniform(-math.pi, math.pi, 6)])  # fmt: skip
    status = ("ok", "ok", "no_return", "ok", "too_near", "ok")
    scan = IrScan(0, 0, 0, (1.2, 2.5, math.nan, 4.0, 0.6, 1.7), status, (2.0,) * 6)
    pose = Pose2D(0.3, -0.2, 0.4)
    model = IrInverseModel()
    together = _grid()
    model.integrate(together, beams_from_scan(pose, 0.02, scan, mounts))
    apart = _grid()
    for k in range(6):
        one = IrScan(0, 0, 0, (scan.ranges_m[k],), (status[k],), (2.0,))
        model.integrate(apart, beams_from_scan(pose, 0.02, one, mounts[k : k + 1]))
    assert np.allclose(together.logodds, apart.logodds, atol=1e-5)


def test_repeated_hits_saturate_at_the_clamp():
    g = _grid(l_max=2.0)
    model = IrInverseModel()
    beams = beams_from_scan(Pose2D(), 0.0, _scan((2.0, "ok")), ONE)
    for _ in range(10):
        model.integrate(g, beams)
    assert _at(g, 2.01, 0.01)[0] == pytest.approx(2.0)
    assert _at(g, 1.0, 0.01)[0] == pytest.approx(-4.0)  # l_min default


def test_beam_leaving_the_map_grows_it_and_keeps_old_cells_in_place():
    g = _grid()
    model = IrInverseModel()
    model.integrate(g, beams_from_scan(Pose2D(), 0.0, _scan((2.0, "ok")), ONE))
    before = g.extent
    mark = _at(g, 2.01, 0.01)[0]
    # From near the east edge (x max 7) looking east 3 m: the grid must grow.
    model.integrate(g, beams_from_scan(Pose2D(6.5, 0.0, 0.0), 0.0, _scan((3.0, "ok")), ONE))
    assert g.extent[2] >= 9.5 and g.extent[0] == before[0]
    assert _at(g, 2.01, 0.01)[0] == mark
    assert _at(g, 9.51, 0.01)[0] == pytest.approx(logit(model.config.p_occupied))
    # Growing to the south (negative side) shifts the origin, not the cells.
    south = g.origin[1]
    model.integrate(
        g, beams_from_scan(Pose2D(0.0, -3.0, -math.pi / 2), 0.0, _scan((3.0, "ok")), ONE)
    )
    assert g.origin[1] < south - 2.0
    assert _at(g, 2.01, 0.01)[0] == mark
    assert _at(g, 0.01, -6.01)[0] == pytest.approx(logit(model.config.p_occupied))
