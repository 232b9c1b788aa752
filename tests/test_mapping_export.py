"""Map export: foxglove.Grid, PNG pictures; map quality against a plan. (Map files for nav2
are tested in test_mapping_mapfile.py.)"""

import json

import numpy as np
import pytest
from matplotlib import image as mpimg

from fakes.world import load
from mapping.export import (
    PICTURE_UNKNOWN,
    from_grid_msg,
    occupancy_probability,
    to_grid_msg,
    write_png,
)
from mapping.grid import GridConfig, OccupancyGrid
from mapping.quality import compare, true_map
from msgs import Pose2D
from msgs.codec import decode, encode
from msgs.mapping import OccupancyGridMsg


def _random_grid(seed=0, shape=(37, 53)):
    rng = np.random.default_rng(seed)
    lo = rng.uniform(-4, 4, shape).astype(np.float32)
    lo[rng.random(shape) < 0.3] = 0.0  # never observed
    return OccupancyGrid.from_array(lo, 0.05, (-1.25, 2.5))


def test_probability_of_a_grid_and_of_its_message_agree():
    g = _random_grid(4)
    p, q = occupancy_probability(g), occupancy_probability(to_grid_msg(g, 1))
    assert np.array_equal(np.isnan(p), g.logodds == 0) and np.array_equal(np.isnan(p), np.isnan(q))
    known = ~np.isnan(p)
    assert np.allclose(p[known], q[known], atol=0.005 + 1e-9)


def test_png_reads_back_as_the_map_picture(tmp_path):
    g = _random_grid(2)
    path = write_png(g, tmp_path / "m.png", scale=2)
    img = mpimg.imread(path)  # floats 0..1, row 0 = top
    assert img.shape == (2 * 37, 2 * 53)
    px = np.round(img[::2, ::2] * 255).astype(int)[::-1]
    unknown = g.logodds == 0
    assert np.all(px[unknown] == PICTURE_UNKNOWN)
    expected = np.round(255 * (1 - g.probability()))
    assert np.array_equal(px[~unknown], expected[~unknown])


def test_foxglove_grid_message_round_trip():
    g = _random_grid(3)
    msg = to_grid_msg(g, 1_500_000_123)
    assert (msg.timestamp.sec, msg.timestamp.nsec) == (1, 500_000_123)
    assert msg.column_count == 53 and msg.cell_size.x == 0.05
    assert (msg.pose.position.x, msg.pose.position.y) == (-1.25, 2.5)
    cells = from_grid_msg(decode(OccupancyGridMsg, encode(msg)))
    assert np.array_equal(cells == -1, g.logodds == 0)
    known = g.logodds != 0
    assert np.array_equal(cells[known], np.round(g.probability()[known] * 100).astype(np.int8))
    assert json.loads(encode(msg))["fields"][0]["name"] == "occupancy"


def test_grid_growth_keeps_cells_and_refuses_absurd_sizes():
    g = OccupancyGrid(GridConfig(resolution_m=0.1, origin_m=(0.0, 0.0), size_m=(2.0, 2.0),
                                 max_cells=100_000))  # fmt: skip
    r, c = g.cell_of(np.array([1.05]), np.array([0.55]))
    g.add(r * g.shape[1] + c, np.array([1.5]))
    assert g.ensure(-0.5, -0.5, 4.0, 1.0)
    assert g.extent[0] <= -0.5 and g.extent[2] > 4.0
    r2, c2 = g.cell_of(np.array([1.05]), np.array([0.55]))
    assert g.logodds[r2, c2][0] == pytest.approx(1.5) and g.logodds.sum() == pytest.approx(1.5)
    assert not g.ensure(0.0, 0.0, 1.0, 1.0)
    with pytest.raises(ValueError, match="max_cells"):
        g.ensure(-1e4, -1e4, 1e4, 1e4)


def test_log_odds_updates_sum_repeats_and_clamp():
    g = OccupancyGrid(GridConfig(resolution_m=1.0, origin_m=(0.0, 0.0), size_m=(3.0, 1.0)))
    g.add(np.array([0, 0, 1, 2]), np.array([0.5, 0.25, -10.0, 10.0]))
    assert g.logodds[0].tolist() == [0.75, -4.0, 4.0] and g.updates == 4
    assert g.trinary().tolist() == [[1, 0, 1]]


def test_match_ratio_precision_recall_against_the_plan():
    plan = load("paper_room")
    g = OccupancyGrid(GridConfig(resolution_m=0.1, origin_m=(-0.5, -0.5), size_m=(8.0, 8.0)))
    truth = true_map(g, plan)
    perfect = OccupancyGrid.from_array(np.where(truth == 1, 3.0, np.where(truth == 0, -3.0, 0.0)),
                                       0.1, (-0.5, -0.5))  # fmt: skip
    q = compare(perfect, plan)
    assert q.match_ratio == 1.0 and q.occupied_precision == 1.0 and q.occupied_recall == 1.0
    assert q.known_both == int((truth >= 0).sum())
    inverted = OccupancyGrid.from_array(-perfect.logodds, 0.1, (-0.5, -0.5))
    assert compare(inverted, plan).match_ratio == 0.0
    # Shifted by one cell: strict scores drop, a one-cell tolerance restores them.
    shifted = OccupancyGrid.from_array(perfect.logodds, 0.1, (-0.4, -0.5))
    strict, tolerant = compare(shifted, plan), compare(shifted, plan, tolerance_cells=1)
    assert strict.occupied_precision < 0.9 and tolerant.occupied_precision > 0.95
    assert strict.match_ratio < 1.0 and tolerant.occupied_recall > 0.95
    # ...and the map_from_grid transform undoes the shift exactly.
    back = compare(shifted, true_map(shifted, plan), map_from_grid=Pose2D(0.0, 0.0, 0.0))
    assert back.match_ratio == strict.match_ratio
    undone = compare(shifted, true_map(shifted, plan), map_from_grid=Pose2D(-0.1, 0.0, 0.0))
    assert undone.match_ratio > 0.99


def test_unknown_cells_do_not_count():
    plan = load("paper_room")
    empty = OccupancyGrid(GridConfig(resolution_m=0.1, origin_m=(-0.5, -0.5), size_m=(8.0, 8.0)))
    q = compare(empty, plan)
    assert q.known_both == 0 and q.match_ratio == 0.0 and q.built_occupied == 0
