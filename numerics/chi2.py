"""Chi-square quantiles for the filters' gates, without importing ``scipy.stats``.

The gates of the heading filter and the pose EKF (ekf-vs-cp eq. 4: a measurement whose
NIS exceeds the chi-square quantile is rejected) need ``chi2.ppf(p, k)`` once per filter,
for small integer degrees of freedom. ``scipy.stats`` takes about a second of CPU to
import (its distribution classes build their docstrings at import), which the daemon,
the replay and every CLI start paid for these few numbers.

For integer ``k`` the distribution function has a closed form in ``math``'s functions
(Abramowitz & Stegun 26.4.4-26.4.5), by the recurrence

    P(x; 1) = erf(sqrt(x / 2)),     P(x; 2) = 1 - exp(-x / 2),
    P(x; k + 2) = P(x; k) - (x / 2)^(k / 2) exp(-x / 2) / Gamma(k / 2 + 1),

used for the upper tail (every term adds to it); below x = k + 2 the lower tail comes
from the incomplete gamma series instead (A&S 6.5.29), which has no cancellation there.
The quantile is found by bisection to the last bit (the function is monotone; about 60
halvings of a bracket), on the smaller tail, so a probability near 1 keeps its digits. ``tests/test_chi2.py`` holds it to ``scipy.stats``.
"""

from __future__ import annotations

import math

__all__ = ["chi2_cdf", "chi2_ppf"]


def _tails(x: float, k: int) -> tuple[float, float]:
    """(P, Q) = (lower, upper) tail of the chi-square distribution with ``k`` dof at x."""
    if x <= 0.0:
        return 0.0, 1.0
    if x == math.inf:
        return 1.0, 0.0
    h, a = 0.5 * x, 0.5 * k
    if h < a + 1.0:
        # lower tail by the incomplete gamma series (A&S 6.5.29), free of the
        # cancellation the recurrence has there: P = h^a e^-h / Gamma(a + 1) *
        # sum_n h^n / ((a + 1) ... (a + n))
        term = total = 1.0
        n = 0
        while term > 1e-17 * total and n < 1000:
            n += 1
            term *= h / (a + n)
            total += term
        p = math.exp(a * math.log(h) - h - math.lgamma(a + 1.0)) * total
        p = min(p, 1.0)
        return p, 1.0 - p
    # upper tail by the recurrence: every term adds to Q
    if k % 2:
        s = math.sqrt(h)
        q = math.erfc(s)
        j = 1
    else:
        q = math.exp(-h)
        j = 2
    log_h = math.log(h)
    while j < k:
        q += math.exp(0.5 * j * log_h - h - math.lgamma(0.5 * j + 1.0))
        j += 2
    q = min(q, 1.0)
    return 1.0 - q, q


def chi2_cdf(x: float, k: int) -> float:
    """P(X <= x) for X chi-square with integer ``k`` >= 1 degrees of freedom."""
    _check_dof(k)
    return _tails(x, k)[0]


def chi2_ppf(probability: float, k: int) -> float:
    """The ``probability`` quantile of the chi-square distribution with integer ``k`` >= 1
    degrees of freedom (``scipy.stats.chi2.ppf``); 0 < probability < 1."""
    _check_dof(k)
    if not 0.0 < probability < 1.0:
        raise ValueError(f"chi-square quantile: probability must be in (0, 1), got {probability!r}")
    upper = probability > 0.5
    target = 1.0 - probability if upper else probability
    lo, hi = 0.0, max(1.0, 2.0 * k)
    while (_tails(hi, k)[1] if upper else -_tails(hi, k)[0]) > (target if upper else -target):
        lo, hi = hi, 2.0 * hi  # widen until the quantile is bracketed
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if mid <= lo or mid >= hi:
            break
        p, q = _tails(mid, k)
        if (q > target) if upper else (p < target):
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def _check_dof(k: int) -> None:
    if int(k) != k or k < 1:
        raise ValueError(f"chi-square: degrees of freedom must be a positive integer, got {k!r}")
