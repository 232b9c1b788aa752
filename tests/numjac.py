"""Central-difference Jacobians for the tests that check analytic ones."""

from __future__ import annotations

import numpy as np

from numerics.angles import wrap


def numeric_jacobian(f, x, eps: float = 1e-7, angular_out: tuple[int, ...] = ()) -> np.ndarray:
    """d f / d x by central differences, one column per component of x; the outputs
    listed in ``angular_out`` are angles, their differences wrapped to (-pi, pi]."""
    x = np.asarray(x, float)
    cols = []
    for i in range(x.size):
        dx = np.zeros_like(x)
        dx[i] = eps
        d = (np.asarray(f(x + dx)) - np.asarray(f(x - dx))).ravel()
        for k in angular_out:
            d[k] = wrap(d[k])
        cols.append(d / (2 * eps))
    return np.stack(cols, axis=1)
