"""Angles wrapped to (-pi, pi] (the convention of every frame in hilnav).

Stdlib at import time: ``msgs`` re-exports :func:`wrap_angle`, and ``import msgs`` must
not import numpy, so :func:`wrap_angles` imports numpy when first called.

- :func:`wrap_angle`: one float, ``math.remainder`` (exact: the result is a - n 2pi
  rounded once), with -pi mapped to pi;
- :func:`wrap_angles`: an array, ``mod(a + pi, 2pi) - pi`` with -pi mapped to pi. The
  sum a + pi is rounded, so an element may differ from :func:`wrap_angle` of it by about
  one unit in the last place of |a| + pi (4.4e-16 rad for |a| < pi);
- :func:`wrap`: either, by argument type (a Python or numpy float -> :func:`wrap_angle`,
  anything else -> :func:`wrap_angles`, a 0-d result as a float).
"""

from __future__ import annotations

import math
from typing import Any

TWO_PI = 2.0 * math.pi


def wrap_angle(a: float) -> float:
    """Wrap an angle in radians to (-pi, pi]."""
    w = math.remainder(a, TWO_PI)
    return math.pi if w == -math.pi else w


def wrap_angles(a: Any) -> Any:
    """Wrap an array (or anything numpy turns into one) of angles to (-pi, pi]."""
    import numpy as np  # deferred: see the module docstring

    w = np.mod(np.asarray(a, dtype=float) + np.pi, TWO_PI) - np.pi
    return np.where(w == -np.pi, np.pi, w)


def wrap(a: Any) -> Any:
    """Wrap angles (array or scalar) to (-pi, pi]: :func:`wrap_angle` for a float,
    :func:`wrap_angles` otherwise (a float when the result has no dimensions)."""
    if isinstance(a, float):
        return wrap_angle(a)
    w = wrap_angles(a)
    return float(w) if w.ndim == 0 else w
