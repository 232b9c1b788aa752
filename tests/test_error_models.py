"""The paper scenario's error models (fakes.world.error_models): each is the distribution
its docstring states, they share one world per seed, and uniform is the scenario of old."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from fakes.world.error_models import (
    ERROR_MODELS,
    OUTSIDE_BOUND,
    SHRINK,
    T3_MEDIAN_ABS,
    bias_signs,
    error,
)
from fakes.world.paper_scenario import simulate

B = 0.2


@pytest.fixture(scope="module")
def u() -> np.ndarray:
    return np.random.default_rng(11).uniform(-1, 1, 200_000)


def test_uniform_is_the_old_draw_and_bias_is_it_shifted(u: np.ndarray) -> None:
    assert np.array_equal(error("uniform", B, u), SHRINK * B * u)
    up, down = error("bias", B, u, 1.0), error("bias", B, u, -1.0)
    assert np.allclose(up - SHRINK * B * u, 0.5 * B) and np.allclose(up, -error("bias", B, -u, -1))
    assert up.min() >= -0.45 * B - 1e-12 and up.max() <= 1.45 * B + 1e-12
    assert np.mean(np.abs(down) > B) == pytest.approx(OUTSIDE_BOUND["bias"], abs=0.003)


def test_gaussian_and_heavy_follow_their_distributions(u: np.ndarray) -> None:
    g = error("gaussian", B, u)
    assert np.std(g) == pytest.approx(B / np.sqrt(3), rel=0.01)
    assert stats.kstest(g / (B / np.sqrt(3)), "norm").pvalue > 0.01
    h = error("heavy", B, u)
    assert pytest.approx(stats.t.ppf(0.75, 3), rel=1e-15) == T3_MEDIAN_ABS
    assert np.median(np.abs(h)) == pytest.approx(0.5 * SHRINK * B, rel=0.01)  # uniform's
    assert stats.kstest(h / (0.5 * SHRINK * B / T3_MEDIAN_ABS), "t", args=(3,)).pvalue > 0.01
    for name, e in (("gaussian", g), ("heavy", h), ("uniform", error("uniform", B, u))):
        assert np.mean(np.abs(e) > B) == pytest.approx(OUTSIDE_BOUND[name], abs=0.003)
    # the quantile map keeps the order of the draws and never gives an infinite error
    assert np.all(np.isfinite(error("heavy", B, np.array([-1.0, 0.0, 1.0]))))
    order = np.argsort(u[:1000])
    assert np.all(np.diff(h[:1000][order]) >= 0)


def test_every_model_sees_the_same_world_and_uniform_stays_inside() -> None:
    worlds = {m: simulate(duration_s=3.0, seed=4, errors=m) for m in ERROR_MODELS}
    ref = worlds["uniform"]
    b = ref.bounds
    assert np.all(np.abs(ref.gyro - ref.truth[:, :, 2]) <= b.gyro_rad)
    assert np.all(np.abs(ref.gps - ref.truth[:, :, :2]) <= b.gps_m)
    for m, sc in worlds.items():
        assert sc.errors == m and np.array_equal(sc.truth, ref.truth)
    # the same draws moved to another distribution: errors keep their signs
    for m in ("gaussian", "heavy"):
        e = worlds[m].gyro - ref.truth[:, :, 2]
        assert np.array_equal(np.sign(e), np.sign(ref.gyro - ref.truth[:, :, 2]))
    assert np.array_equal(bias_signs(4, 0, 5), bias_signs(4, 0, 5))
    assert set(bias_signs(4, 1000, 64)) == {-1.0, 1.0}
    with pytest.raises(ValueError, match="error model 'cauchy'"):
        simulate(duration_s=1.0, errors="cauchy")
