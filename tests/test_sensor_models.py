import numpy as np
import pytest

from drivers.sharp import STATUS_NAMES, MedianFilter, SharpCurve
from fakes.world.gps_model import GpsErrorModel
from fakes.world.gyro_model import GyroErrorModel
from fakes.world.ir_model import IrErrorModel


def test_curve_round_trip_in_valid_range():
    c = SharpCurve()
    d = np.linspace(1.0, 5.5, 40)
    r, s = c.range(c.voltage(d))
    assert np.all(s == 0)
    np.testing.assert_allclose(r, d, rtol=1e-9)


def test_table_points_are_exact():
    c = SharpCurve()
    np.testing.assert_allclose(c.voltage(np.array([1.0, 2.0, 3.5])), [2.5, 1.8, 1.5])


@pytest.mark.parametrize(
    "true_m,status",
    [(0.7, "too_near"), (7.0, "too_far"), (np.inf, "no_return"), (2.0, "ok")],
)
def test_flags(true_m, status):
    c = SharpCurve()
    _, s = c.range(c.voltage(np.array([true_m])))
    assert STATUS_NAMES[s[0]] == status


def test_near_obstacle_reads_far():
    c = SharpCurve()
    r, s = c.range(c.voltage(np.array([0.2])))
    assert s[0] == 0 and r[0] > 2.5  # the near-range ambiguity


def test_impossible_voltage_is_invalid():
    _, s = SharpCurve().range(np.array([4.0, np.nan]))
    assert list(s) == [4, 4]


def test_bad_calibration_table():
    with pytest.raises(ValueError, match="increase"):
        SharpCurve((1.0, 1.0), (2.0, 1.0))


def test_median_filter_removes_a_spike():
    f = MedianFilter(1, 3)
    out = [f(np.array([x]))[0] for x in (2.0, 9.0, 2.1)]
    assert out[-1] == pytest.approx(2.1)


def test_ir_model_counts_decode_near_truth():
    m = IrErrorModel(dropout_prob=0.0)
    rng = np.random.default_rng(0)
    d = np.full(500, 1.5)
    r, s = m.curve.range(m.volts(m.counts(d, rng)))
    assert np.all(s == 0)
    assert abs(np.median(r) - 1.5) < 0.03


def test_gyro_model_bias_and_noise():
    g = GyroErrorModel(seed=1)
    rates = np.array([g.sample(0.0, 0.01) for _ in range(2000)])
    assert abs(rates.mean() - g.bias_radps) < 0.003
    assert 0.5 * 0.015 * np.pi / 180 * 10 < rates.std() < 2 * 0.015 * np.pi / 180 * 10


def test_gps_model_outages_and_spread():
    m = GpsErrorModel(seed=2, outage_rate_per_s=0.05, outage_mean_s=5)
    errs = [m.sample(1.0) for _ in range(2000)]
    got = np.array([e for e in errs if e is not None])
    assert 0 < len(got) < 2000
    assert 0.5 < got[:, 0].std() < 3.0


def test_median_filter_equals_numpy_median():
    rng = np.random.default_rng(3)
    for n in (1, 2, 3, 4, 5):
        f = MedianFilter(4, n)
        hist: list[list[float]] = [[] for _ in range(4)]
        for _ in range(30):
            x = rng.uniform(0.5, 6.0, 4)
            x[rng.random(4) < 0.2] = np.nan
            x[rng.random(4) < 0.05] = np.inf
            out = f(x)
            for i in range(4):
                hist[i] = (hist[i] + [float(x[i])])[-n:]
                vals = [v for v in hist[i] if np.isfinite(v)]
                expect = float(np.median(vals)) if vals else np.nan
                assert out[i] == expect or (np.isnan(out[i]) and np.isnan(expect))
