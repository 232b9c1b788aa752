"""Map scores (mapping.map_scores) rank maps as a person would, on a slice of the Intel log:
the six-beam IR map at the reference poses beats the same map shifted or rotated, on the
same cells, where the paper's match ratio hardly moves."""

from __future__ import annotations

import math
from functools import cache

import numpy as np
import pytest

from hilnav.importers.carmen import emulate, reference_map
from mapping.carmen import load_laser_log
from mapping.grid import GridConfig, OccupancyGrid
from mapping.ir_inverse import IrInverseModel, beams_from_scan
from mapping.map_scores import ReferenceMap, score
from msgs import Pose2D
from tests.conftest import SHARED, require

INTEL = SHARED / "data" / "intel"
DEG = math.pi / 180.0
MOUNTS = np.array([[0.2, 0.05, 15 * DEG], [0.2, -0.05, -15 * DEG], [0.17, 0.13, 50 * DEG],
                   [0.17, -0.13, -50 * DEG], [0.0, 0.19, 90 * DEG], [0.0, -0.19, -90 * DEG]])  # fmt: skip


@cache
def _run():
    log = load_laser_log(
        require(INTEL / "sot_scan_intel.mat"), require(INTEL / "intel.gfs.log")
    ).head(700)
    run = emulate(log, MOUNTS)
    return run, reference_map(run, 0.05, (-1.0, -1.0))


def _map(dx: float = 0.0, dy: float = 0.0, dth: float = 0.0) -> OccupancyGrid:
    """The IR map at the reference poses, moved rigidly by (dx, dy, dth) about the start."""
    run, _ = _run()
    ref = run.log.reference
    g = OccupancyGrid(GridConfig(origin_m=(-1.0, -1.0)))
    model = IrInverseModel()
    x0, y0 = ref[0, 0], ref[0, 1]
    c, s = math.cos(dth), math.sin(dth)
    for p, scan in zip(ref, run.scans, strict=True):
        qx, qy = p[0] - x0, p[1] - y0
        pose = Pose2D(x0 + c * qx - s * qy + dx, y0 + s * qx + c * qy + dy, p[2] + dth)
        model.integrate(g, beams_from_scan(pose, 0.0, scan, MOUNTS))
    return g


def test_shifted_and_rotated_maps_score_worse_on_the_same_cells() -> None:
    _, laser = _run()
    best = _map()
    ref = laser.with_observed(best)
    s0 = score(best, ref)
    assert s0.occupied_precision > 0.85 and s0.occupied_recall > 0.9 and s0.alignment > 0.9
    worse = [score(_map(0.2, 0.1), ref), score(_map(dth=3 * DEG), ref)]
    for s in worse:
        assert s.reference_walls == s0.reference_walls  # the same cells for every map
        assert s.reference_free == s0.reference_free
        assert s.occupied_precision < s0.occupied_precision - 0.15
        assert s.occupied_recall < s0.occupied_recall - 0.1
        assert s.alignment < s0.alignment - 0.08
        # The paper's match ratio barely notices (free cells dominate).
        assert s0.match_ratio - s.match_ratio < 0.08
    # Bigger errors score lower still.
    assert score(_map(dth=6 * DEG), ref).alignment < worse[1].alignment


def test_degenerate_maps_score_low() -> None:
    _, laser = _run()
    best = _map()
    ref = laser.with_observed(best)
    empty = OccupancyGrid(GridConfig(origin_m=(-1.0, -1.0)))
    s = score(empty, ref)
    assert s.occupied_precision == 0.0 and s.occupied_recall == 0.0 and s.alignment == 0.0
    full = best.copy()
    full.logodds[:] = 4.0  # everything occupied: finds every wall, fits nothing
    s = score(full, ref)
    assert s.occupied_recall == 1.0 and s.occupied_precision < 0.2 and s.alignment <= 0.5
    with pytest.raises(ValueError, match="shape"):
        ReferenceMap(ref.cells, 0.05, (0.0, 0.0), observed=np.zeros((2, 2), dtype=bool))
