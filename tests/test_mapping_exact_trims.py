"""The mapping's trimmed computations give what the plain ones give, bit for bit.

- ``mapping.ir_cone._mod_two_pi`` / ``_wrap_abs`` with ``finite`` (no check for values
  beyond 2**20 turns or NaN, which the caller rules out) against ``np.mod``;
- ``mapping.ir_cone.cell_updates`` without the clamps before eq. 6's arcsin, against the
  plain lattice of ``mapping.ir_reference`` on beams whose origins sit on cell centres
  and corners (cells within the cell radius);
- ``mapping.se2.compose`` of one pose against the array path.
"""

from __future__ import annotations

import math

import numpy as np

import mapping.ir_cone as ir_cone
from mapping.grid import GridConfig, OccupancyGrid
from mapping.ir_inverse import KIND_CLEAR, KIND_HIT, Beams, IrInverseModel
from mapping.ir_reference import reference_updates
from mapping.se2 import compose
from numerics.angles import wrap_angles


def test_the_finite_wrap_equals_numpy_mod():
    rng = np.random.default_rng(4)
    two_pi = 2.0 * math.pi
    vals = [rng.uniform(-(2.0**18), 2.0**18, 200_000), rng.uniform(-50, 50, 200_000)]
    for k in range(-2000, 2001, 3):
        c = k * two_pi
        vals.append(np.array([c, np.nextafter(c, np.inf), np.nextafter(c, -np.inf), -0.0, 0.0]))
    a = np.concatenate(vals)
    np.testing.assert_array_equal(ir_cone._mod_two_pi(a, True), np.mod(a, two_pi))
    np.testing.assert_array_equal(ir_cone._wrap_abs(a, False, True), np.abs(wrap_angles(a)))
    assert ir_cone._mod_two_pi(a, True).tobytes() == np.mod(a, two_pi).tobytes()


def _beams(rng: np.random.Generator, n: int, res: float) -> Beams:
    # Origins on cell centres and corners: the cells within the cell radius of eq. 6.
    x = (rng.integers(-20, 20, n) + rng.choice([0.0, 0.5], n)) * res
    y = (rng.integers(-20, 20, n) + rng.choice([0.0, 0.5], n)) * res
    kind = rng.choice([KIND_HIT, KIND_HIT, KIND_CLEAR], n).astype(np.int8)
    rng_m = np.where(kind == KIND_HIT, rng.uniform(0.02, 3.0, n), np.nan)
    angle = rng.uniform(-40.0, 40.0, n)  # unwrapped headings: the fmod path
    return Beams(x, y, angle, rng_m, kind, np.full(n, rng.uniform(0.0, 0.1)))


def test_cell_updates_equal_the_reference_within_the_cell_radius():
    rng = np.random.default_rng(11)
    for res in (0.05, 0.1):
        model = IrInverseModel()
        for _ in range(30):
            beams = _beams(rng, 7, res)
            cfg = GridConfig(resolution_m=res, origin_m=(-3.0, -3.0))
            fast, ref = OccupancyGrid(cfg), OccupancyGrid(cfg)
            flat, dl = model.updates(fast, beams)
            want_flat, want_dl = reference_updates(model, ref, beams)
            assert fast.origin == ref.origin and fast.shape == ref.shape
            assert flat.tobytes() == np.asarray(want_flat, dtype=np.int64).tobytes()
            assert dl.tobytes() == np.asarray(want_dl, dtype=np.float64).tobytes()


def test_compose_of_one_pose_equals_the_array_path():
    rng = np.random.default_rng(5)
    a = rng.normal(0.0, 20.0, (5000, 3))
    b = rng.normal(0.0, 1.0, (5000, 3))
    many = compose(a, b)
    one = np.array([compose(p, q) for p, q in zip(a, b, strict=True)])
    assert many.tobytes() == one.tobytes()
