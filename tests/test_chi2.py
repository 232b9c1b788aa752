"""numerics.chi2 against scipy.stats (the filters' gates without importing scipy.stats)."""

import math
import subprocess
import sys

import numpy as np
import pytest
from scipy.stats import chi2

from numerics.chi2 import chi2_cdf, chi2_ppf

PROBS = [1e-12, 1e-6, 0.01, 0.05, 0.3, 0.5, 0.7, 0.9, 0.95, 0.99, 0.997, 0.9999, 1 - 1e-9]


@pytest.mark.parametrize("k", list(range(1, 13)) + [20, 31, 60, 101])
def test_quantile_matches_scipy(k: int) -> None:
    for p in PROBS:
        assert chi2_ppf(p, k) == pytest.approx(chi2.ppf(p, k), rel=1e-12)


def test_distribution_function_matches_scipy_and_inverts() -> None:
    rng = np.random.default_rng(7)
    for _ in range(400):
        k = int(rng.integers(1, 80))
        x = float(rng.gamma(k / 2.0, 2.0) * rng.uniform(0.2, 2.0))
        assert chi2_cdf(x, k) == pytest.approx(chi2.cdf(x, k), rel=1e-11, abs=1e-300)
        p = float(rng.uniform(0.001, 0.999))
        assert chi2_cdf(chi2_ppf(p, k), k) == pytest.approx(p, rel=1e-12)
    assert chi2_cdf(0.0, 3) == 0.0 and chi2_cdf(-1.0, 1) == 0.0
    assert chi2_cdf(math.inf, 2) == 1.0 and chi2_cdf(math.inf, 5) == 1.0


@pytest.mark.parametrize(
    "p, k", [(0.0, 1), (1.0, 1), (-0.1, 2), (math.nan, 2), (0.5, 0), (0.5, 1.5)]
)
def test_bad_arguments_are_clear_errors(p: float, k: float) -> None:
    with pytest.raises(ValueError):
        chi2_ppf(p, k)  # type: ignore[arg-type]


def test_the_filters_do_not_import_scipy_stats() -> None:
    code = (
        "import sys, hilnav.pipeline, hilnav.daemon, hilnav.replay.replayer\n"
        "from fusion.heading import HeadingFilter\n"
        "from fusion.heading_params import HeadingParams\n"
        "HeadingFilter(HeadingParams())\n"
        "print('scipy.stats' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
