"""The association's faster computations give what the plain ones give, bit for bit.

- ``IrInverseModel.integrate_each`` (the drift branches' maps from one computation per
  origin) against one ``integrate`` per grid;
- the memo's modes: the map keeps, the reference map takes, a robot standing still
  (beams repeated bit for bit) no longer wipes what the reference map has not taken;
- ``FieldBeamModel.terms`` (a framed table of codes, first obstacle and first unknown
  by one argmax each) against the per-point lookup it replaced;
- a whole run of :class:`SampleAssociation` (loop checks, the drift test adopting a
  drift, re-insertion) against the same run computed the former way: no memo, one
  insertion per branch into maps of their own from the start, np.mod's angle wrap, the
  per-point lookup.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from ir_drive import MOUNTS, drifted, ir_scans, truth_path

import mapping.association as association_module
import mapping.ir_cone as ir_cone
from mapping.association import AssociationConfig, SampleAssociation
from mapping.beam_model import FieldBeamModel, distance_cells, unknown_p
from mapping.grid import GridConfig, OccupancyGrid
from mapping.heading_drift import DriftBank
from mapping.ir_inverse import KIND_CLEAR, KIND_HIT, KIND_SKIP, Beams, IrInverseModel
from mapping.se2 import compose
from numerics.angles import wrap_angles

GRID = GridConfig(resolution_m=0.1, origin_m=(-1.0, -1.0), size_m=(9.0, 9.0))


def _bits(g: OccupancyGrid) -> tuple:
    return g.origin, g.shape, g.logodds.view(np.uint32).tobytes()


def _scan(rng: np.random.Generator, n: int = 6) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(ranges, kinds, sigmas) of one scan with every kind of reading."""
    kind = rng.choice([KIND_HIT, KIND_HIT, KIND_CLEAR, KIND_SKIP], n).astype(np.int8)
    ranges = np.where(kind == KIND_HIT, rng.uniform(0.1, 6.0, n), np.nan)
    return ranges, kind, np.full(n, rng.uniform(0.0, 0.2))


def test_the_angle_wrap_equals_numpy_mod_far_from_zero():
    """Eq. 6's wrap of the angle to a cell (mapping.ir_cone): the association's headings
    are not wrapped (tens of radians after loops). Without np.mod, bit for bit: values
    over many turns, around every multiple of 2 pi up to 3000 turns, beyond 2**20 turns
    (np.mod itself), non-finite values; the one-add path where the beams' angles allow."""
    rng = np.random.default_rng(9)
    two_pi = 2.0 * math.pi
    edges = [-0.0, 0.0, 1e-300, -1e-17, 1e300, -1e300, math.nan, math.inf, -math.inf]
    for k in range(-3000, 3001, 7):
        for c in (k * two_pi, k * two_pi - math.pi):
            up = down = c
            for _ in range(3):
                edges += [up, down]
                up, down = np.nextafter(up, np.inf), np.nextafter(down, -np.inf)
    cases = [rng.uniform(-60, 60, 50_000), rng.uniform(-2e4, 2e4, 50_000),
             rng.uniform(-1e8, 1e8, 2_000), np.array(edges)]  # fmt: skip
    with np.errstate(invalid="ignore"):
        for a in cases:
            np.testing.assert_array_equal(ir_cone._mod_two_pi(a), np.mod(a, two_pi))
            np.testing.assert_array_equal(ir_cone._wrap_abs(a), np.abs(wrap_angles(a)))
        # Beams' angles within (-2 pi, 2 pi): alpha = atan2 - angle lies in (-3 pi, 3 pi).
        near = rng.uniform(-math.pi, math.pi, 50_000) - rng.uniform(-6.28, 6.28, 50_000)
        np.testing.assert_array_equal(ir_cone._wrap_abs(near, True), np.abs(wrap_angles(near)))


def test_integrate_each_equals_one_integrate_per_grid():
    rng = np.random.default_rng(7)
    model = IrInverseModel()
    for case in range(12):
        ranges, kind, sigma = _scan(rng, 12)
        keep = kind != KIND_SKIP
        ranges, kind, sigma = ranges[keep], kind[keep], sigma[keep]
        poses = [rng.uniform([-2, -2, -40], [2, 2, 40], (len(kind), 3)) for _ in range(4)]
        beams = [Beams(p[:, 0], p[:, 1], p[:, 2], ranges, kind, sigma) for p in poses]
        # Grids of one origin, one grown elsewhere, one small that must grow.
        grids = [OccupancyGrid(GRID), OccupancyGrid(GRID),
                 OccupancyGrid(GridConfig(resolution_m=0.1, origin_m=(-1.3, -0.7))),
                 OccupancyGrid(GridConfig(resolution_m=0.1, size_m=(1.0, 1.0)))]  # fmt: skip
        for g in grids:
            g.add(np.arange(0, g.logodds.size, 7), np.full(len(range(0, g.logodds.size, 7)), 3.9))
        plain = [g.copy() for g in grids]
        if case % 3 == 2:
            model.max_samples_per_call = 30_000  # integrate applies it in parts
        want = sum(model.integrate(g, b, "off") for g, b in zip(plain, beams, strict=True))
        assert model.integrate_each(grids, beams) == want
        model.max_samples_per_call = 400_000
        for g, p in zip(grids, plain, strict=True):
            assert _bits(g) == _bits(p)
    # Beams that do not share their readings: one integrate each.
    other = Beams(*(np.copy(a) for a in (beams[0].x, beams[0].y, beams[0].angle, ranges,
                                         kind, sigma)))  # fmt: skip
    a, b = OccupancyGrid(GRID), OccupancyGrid(GRID)
    model.integrate_each([a, b], [beams[0], other])
    assert _bits(a) == _bits(b)


def test_the_reference_map_reuses_the_beams_of_a_robot_standing_still():
    """Scan i into map A, into map B three scans later; the robot stands still for a
    while (its beams repeat bit for bit). B equals B built without the memo, and B
    computes again only a beam it has taken before: A's hits on the repeats forget
    nothing (with the former mode, "use" for both, they wiped B's entries)."""
    rng = np.random.default_rng(3)
    pose = np.array([1.0, 2.0, 0.3])
    scans = []
    for i in range(16):
        if 4 <= i < 10:  # standing still: the same scan again
            scans.append(scans[-1])
            continue
        pose = pose + rng.normal(0.0, [0.03, 0.03, 0.05])
        ranges, kind, sigma = _scan(rng)
        sens = compose(np.broadcast_to(pose, MOUNTS.shape), MOUNTS)
        keep = kind != KIND_SKIP
        scans.append(Beams(*(v[keep] for v in (sens[:, 0], sens[:, 1], sens[:, 2], ranges,
                                                kind, sigma))))  # fmt: skip
    b_plain = OccupancyGrid(GRID)
    plain = IrInverseModel()
    for i in range(3, len(scans)):
        plain.integrate(b_plain, scans[i - 3])

    def run(first: str, second: str, cells: int = 10**7) -> tuple[IrInverseModel, int, int]:
        model = IrInverseModel(reuse_cells=cells)
        a, b = OccupancyGrid(GRID), OccupancyGrid(GRID)
        misses, again, seen = 0, 0, set()
        for i, beams in enumerate(scans):
            model.integrate(a, beams, first)
            if i >= 3:
                took = scans[i - 3]
                m0 = model._memo.misses  # type: ignore[union-attr]
                model.integrate(b, took, second)
                misses += model._memo.misses - m0  # type: ignore[union-attr]
                again += len(took) if id(took) in seen else 0
                seen.add(id(took))
            assert model._memo is not None and model._memo.cells <= cells
        assert _bits(b) == _bits(b_plain)
        return model, misses, again

    model, misses, again = run("keep", "take")
    assert 0 < misses <= again  # only beams B had taken before
    assert len(model._memo._kept) == sum(len(s) for s in scans[-3:])  # what B has not taken
    _, misses_before, _ = run("use", "use")
    assert misses_before > again
    run("keep", "take", cells=2_000)  # the bound holds (the oldest make room), same maps
    with pytest.raises(ValueError, match="memo"):
        model.integrate(OccupancyGrid(GRID), scans[0], "both")


class PlainField(FieldBeamModel):
    """:class:`FieldBeamModel` with the per-point lookup and the ray tests it replaced."""

    def _plain(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        assert self.dist is not None and self.known is not None
        rows, cols = self.dist.shape
        c = np.floor((x - self.origin[0]) / self.res)
        r = np.floor((y - self.origin[1]) / self.res)
        inside = (r >= 0) & (r < rows) & (c >= 0) & (c < cols)
        ri, ci = np.where(inside, r, 0).astype(int), np.where(inside, c, 0).astype(int)
        return (np.where(inside, self.dist[ri, ci], np.float32(np.inf)),
                np.where(inside, self.known[ri, ci], False))  # fmt: skip

    def terms(self, poses, sens, ranges, kinds):
        cfg = self.cfg
        z_max = cfg.max_range_m
        world = compose(poses[:, None, :], sens[None, :, :])
        c, s = np.cos(world[..., 2]), np.sin(world[..., 2])
        clear = kinds == KIND_CLEAR
        z = np.where(clear, z_max, np.nan_to_num(ranges, nan=z_max))
        sig = np.hypot(cfg.sigma_hit_m, cfg.sigma_hit_per_m2 * z**2)
        d_end, _ = self._plain(world[..., 0] + c * z, world[..., 1] + s * z)
        t = np.arange(self.step_m, z_max + 1e-9, self.step_m)
        reach = np.where(clear, z_max, z - 1.5 * sig)
        px = world[..., 0][..., None] + c[..., None] * t
        py = world[..., 1][..., None] + s[..., None] * t
        d_ray, known = self._plain(px, py)
        on_ray = t[None, None, :] <= reach[None, :, None]
        wall = d_ray < 0.75 * self.res
        blocked = np.any(on_ray & wall, axis=-1)
        first_wall = np.where(wall.any(-1), t[np.argmax(wall, axis=-1)], np.inf)
        unk = on_ray & ~known
        first_unk = np.where(unk.any(-1), t[np.argmax(unk, axis=-1)], np.inf)
        blind = first_unk < first_wall
        with np.errstate(over="ignore"):
            p_hit = np.exp(-0.5 * (d_end / sig) ** 2) / (sig * math.sqrt(2 * math.pi))
        p_hit = np.where(blocked, 0.0, p_hit)
        p_rand = 1.0 / z_max
        p = np.where(clear[None, :], cfg.a_max * (~blocked) + cfg.a_rand * p_rand,
                     cfg.a_hit * p_hit + cfg.a_rand * p_rand)  # fmt: skip
        p = np.where(blind, unknown_p(cfg, clear[None, :]), p)
        return np.log(p), blind


def test_field_terms_equal_the_per_point_lookup():
    """Maps with walls, free and never observed space; boxes cut by the map's edge, so
    rays leave the field; samples inside and far outside it."""
    rng = np.random.default_rng(11)
    cfg = AssociationConfig()
    for case in range(6):
        g = OccupancyGrid(GRID)
        lo = rng.choice([0.0, -2.0, -1.0, 3.0], g.shape, p=[0.3, 0.4, 0.2, 0.1])
        g.logodds[:] = lo.astype(np.float32)
        box = (-4.0, 0.5, 4.0, 9.5) if case % 2 else None
        fast, plain = FieldBeamModel(cfg), PlainField(cfg)
        fast.set_map(g, box)
        plain.set_map(g, box)
        poses = rng.uniform([-3, -3, -9], [10, 10, 9], (60, 3))
        ranges, kinds, _ = _scan(rng, 30)
        keep = kinds != KIND_SKIP
        sens = rng.uniform([-0.2, -0.2, -3.2], [0.2, 0.2, 3.2], (int(keep.sum()), 3))
        got = fast.terms(poses, sens, ranges[keep], kinds[keep])
        want = plain.terms(poses, sens, ranges[keep], kinds[keep])
        np.testing.assert_array_equal(got[0].view(np.uint64), want[0].view(np.uint64))
        np.testing.assert_array_equal(got[1], want[1])
        assert want[1].any() and not want[1].all()  # blind and seeing beams both


class FormerBank(DriftBank):
    """The drift test as first written: a map per branch from the start, one insertion
    per branch, everything through the model's memo."""

    def __init__(self, cfg, drift, spacing, start, pose, ref, ref_upto, next_travel=0.0, *,
                 mounts):  # fmt: skip
        super().__init__(cfg, drift, spacing, start, pose, ref, ref_upto, next_travel,
                         mounts=mounts)  # fmt: skip
        for b in self.branches:
            b.ref = ref.copy()

    def age(self, rec, upto, model, per_branch):
        a, updates = self.ref_upto, 0
        upto = min(upto, a + max(per_branch, 1))
        if upto <= a:
            return 0
        cut = min(max(self.start, a), upto)
        for b in self.branches:
            if cut > a:
                updates += model.integrate(b.ref, rec.beams(a, cut))
            if upto > cut:
                own = np.array(b.poses[cut - self.start : upto - self.start])
                updates += model.integrate(b.ref, rec.beams(cut, upto, own))
        self.ref_upto = upto
        return updates


def _run(former: bool, monkeypatch: pytest.MonkeyPatch) -> SampleAssociation:
    truth = truth_path(30.0)
    scans, est = ir_scans(truth, 3), drifted(truth, 1.03, scale_sigma=0.02)
    cfg = AssociationConfig(drift_sigma_per_rad=0.01, check_every_m=2.0)
    with monkeypatch.context() as m:
        if former:
            m.setattr(association_module, "DriftBank", FormerBank)
            m.setattr(
                ir_cone, "_wrap_abs", lambda a, near=False, finite=False: np.abs(wrap_angles(a))
            )
        da = SampleAssociation(MOUNTS, cfg, GRID, seed=2)
        if former:
            da.model = IrInverseModel(da.model.config)  # no memo
            da.model.integrate_each = lambda grids, beams: sum(  # type: ignore[method-assign]
                da.model.integrate(g, b) for g, b in zip(grids, beams, strict=True))  # fmt: skip
            da._field = PlainField(cfg)
        for h, s in zip(est, scans, strict=True):
            da.step(h, s)
    return da


def test_the_association_equals_its_former_computation(monkeypatch):
    fast, former = _run(False, monkeypatch), _run(True, monkeypatch)
    counts = fast.outcome_counts()
    assert counts["drift"] >= 1 and counts["confirmed"] >= 1 and counts["unconfirmed"] >= 1
    assert fast.model._memo is not None and fast.model._memo.hits > 0
    assert fast.reports == former.reports
    np.testing.assert_array_equal(
        fast.trajectory.view(np.uint64), former.trajectory.view(np.uint64)
    )
    assert _bits(fast.grid) == _bits(former.grid)
    assert _bits(fast._ref) == _bits(former._ref)
    assert fast.cell_updates == former.cell_updates


def test_grid_add_on_a_wide_map_sums_in_the_cells_box_like_np_unique():
    """A scan's cells span many rows of a wide map: summed in the box of their rows and
    columns, bit for bit as np.unique's path sums them (in their given order)."""
    rng = np.random.default_rng(13)
    for trial in range(30):
        g = OccupancyGrid(GridConfig(size_m=(80.0, 60.0), resolution_m=0.05))
        rows, cols = g.shape
        n = int(rng.integers(1, 3000))
        r = rng.integers(0, 60, n) + rng.integers(0, rows - 60)
        c = rng.integers(0, 50 if trial % 3 else cols, n) + (
            rng.integers(0, cols - 50) if trial % 3 else 0
        )
        idx = r * cols + c
        assert idx.max() - idx.min() > 4 * n + 65536 or trial % 3 == 0
        for _ in range(3):
            dl = rng.normal(0.0, 2.0, n)
            want = g.logodds.reshape(-1).copy()
            t, inv = np.unique(idx, return_inverse=True)
            tot = np.bincount(inv, weights=dl) + want[t]
            want[t] = np.clip(tot, g.config.l_min, g.config.l_max)
            assert g.add(idx, dl) == n
            np.testing.assert_array_equal(
                g.logodds.reshape(-1).view(np.uint32), want.view(np.uint32)
            )


def test_the_distance_field_equals_scipys_bit_for_bit():
    """The association's distance field (the ``edt`` library's squared distances, the
    root in float64) is scipy.ndimage's ``distance_transform_edt``, bit for bit: random
    maps of every density and shape, a single obstacle in a corner, a row and a column,
    and a field too large for float32's exact integers (scipy's own path)."""
    from scipy.ndimage import distance_transform_edt

    rng = np.random.default_rng(7)
    cases = [rng.random((r, c)) >= p for r, c, p in
             [(260, 260, 0.02), (61, 307, 0.005), (1, 50, 0.1), (50, 1, 0.1), (7, 9, 0.5),
              (240, 200, 0.0005), (3, 3, 0.9)]]  # fmt: skip
    corner = np.ones((120, 90), dtype=bool)
    corner[0, 0] = False
    wide = np.ones((1, 4100), dtype=bool)
    wide[0, 17] = False
    for free in [*cases, corner, wide]:
        if free.all():
            free[0, 0] = False
        got = distance_cells(free)
        want = distance_transform_edt(free)
        assert got.dtype == np.float64 and got.shape == free.shape
        assert np.array_equal(got, want), free.shape
        assert np.array_equal((got * 0.05).astype(np.float32), (want * 0.05).astype(np.float32))
    window = rng.random((300, 400)) >= 0.01
    for view in (window[17:211, 33:301], window[::2, ::3], window.T, window[::-1, 5:]):
        assert np.array_equal(distance_cells(view), distance_transform_edt(view))
    for shape in ((4, 4), (1, 4100)):  # no obstacle: infinitely far, on both paths
        none = distance_cells(np.ones(shape, dtype=bool))
        assert none.dtype == np.float64 and np.all(np.isposinf(none))
