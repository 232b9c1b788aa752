"""Pose algebra on arrays of planar poses (..., 3) = (x, y, theta), as the sample-based
data association of ir-grid-mapping §4 (eq. 7-8) uses it on its sample cloud, its sensor
mounts and its scan records: composition and the relative pose (angles wrapped by
``numerics.angles``).
"""

from __future__ import annotations

import numpy as np

from numerics.angles import wrap, wrap_angles

__all__ = ["compose", "relative", "wrap"]


def compose(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Pose composition a (+) b on (..., 3) arrays."""
    if a.ndim == 1 and b.ndim == 1:  # one pose: the same float64 operations, no stack
        c, s = np.cos(a[2]), np.sin(a[2])
        ax, ay, at = a.tolist()
        bx, by, bt = b.tolist()
        return np.array([ax + c * bx - s * by, ay + s * bx + c * by, at + bt])
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    return np.stack(
        [
            a[..., 0] + c * b[..., 0] - s * b[..., 1],
            a[..., 1] + s * b[..., 0] + c * b[..., 1],
            a[..., 2] + b[..., 2],
        ],
        axis=-1,
    )


def relative(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(-a) (+) b: pose b in the frame of pose a."""
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    dx, dy = b[..., 0] - a[..., 0], b[..., 1] - a[..., 1]
    dth = wrap_angles(b[..., 2] - a[..., 2])
    return np.stack([c * dx + s * dy, -s * dx + c * dy, dth], axis=-1)
