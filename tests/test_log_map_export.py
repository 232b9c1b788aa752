"""``hilnav map export``: the last map of a log, or the one at/before a time, as nav2 files."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from hilnav.cli import main
from hilnav.log.writer import LogWriter
from mapping.export import to_grid_msg
from mapping.grid import OccupancyGrid
from msgs import GyroSample
from tests.test_mapping_mapfile import nav2_load

T0 = 1_000_000_000_000
S = 1_000_000_000


def _grid(fill: float, shape: tuple[int, int] = (20, 30)) -> OccupancyGrid:
    """A grid whose left half is ``fill`` (log-odds) and right half never observed."""
    lo = np.zeros(shape, dtype=np.float32)
    lo[:, : shape[1] // 2] = fill
    return OccupancyGrid.from_array(lo, 0.1, (-1.0, -2.0))


def _log(path: Path) -> None:
    """r1 maps at 1 s (occupied) and 5 s (free), r2 a map at 3 s, gyro until 8 s."""
    with LogWriter(path, wall_clock=False) as w:
        for i in range(81):
            t = T0 + i * S // 10
            w.write("/r1/gyro", GyroSample(t, 0.0, 0.0), t)
        w.write("/r1/map", to_grid_msg(_grid(3.0), T0 + S), T0 + S)
        w.write("/r2/map", to_grid_msg(_grid(3.0), T0 + 3 * S), T0 + 3 * S)
        w.write("/r1/map", to_grid_msg(_grid(-3.0), T0 + 5 * S), T0 + 5 * S)


def _export(capsys, *argv: str) -> dict:
    assert main(["map", "export", *argv]) == 0
    return json.loads(capsys.readouterr().out.strip().splitlines()[-1])


def test_export_last_map_and_map_at_a_time(tmp_path, capsys):
    log = tmp_path / "run.mcap"
    _log(log)
    out = tmp_path / "maps"
    rep = _export(capsys, str(log), "--out", str(out), "--robot", "r1")
    assert rep["robot"] == "r1" and rep["at_s"] == 5.0 and rep["mode"] == "trinary"
    assert sorted(p.name for p in out.iterdir()) == ["r1_map.pgm", "r1_map.png", "r1_map.yaml"]
    nav2 = nav2_load(out / "r1_map.yaml")
    assert nav2["resolution"] == 0.1 and nav2["origin"] == [-1.0, -2.0, 0.0]
    assert np.all(nav2["cells"][:, :15] == 0) and np.all(nav2["cells"][:, 15:] == -1)
    assert rep["free_cells"] == 300 and rep["unknown_cells"] == 300
    assert Image.open(out / "r1_map.png").size[0] >= 30  # the picture, scaled up
    # --at 4.0: the map logged at 1 s (occupied), not the later one.
    rep = _export(capsys, str(log), "--out", str(out), "--robot", "r1", "--at", "4")
    assert rep["at_s"] == 1.0 and rep["occupied_cells"] == 300
    assert np.all(nav2_load(out / "r1_map.yaml")["cells"][:, :15] == 100)


def test_scale_export_is_an_rgba_png_with_transparent_unknown(tmp_path, capsys):
    log = tmp_path / "run.mcap"
    _log(log)
    rep = _export(capsys, str(log), "--out", str(tmp_path), "--robot", "r2", "--mode", "scale")
    assert rep["unknown_cells"] == 300 and rep["files"][0].endswith("r2_map.png")
    assert Image.open(tmp_path / "r2_map.png").mode == "RGBA"
    assert np.all(nav2_load(tmp_path / "r2_map.yaml")["cells"][:, 15:] == -1)


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        ((), "holds the maps of r1, r2"),
        (("--robot", "r3"), "no map of robot 'r3'"),
        (("--robot", "r1", "--at", "0.5"), "no map of r1 at or before 0.5 s"),
    ],
)
def test_export_errors_name_the_problem(tmp_path, capsys, extra, message):
    log = tmp_path / "run.mcap"
    _log(log)
    assert main(["map", "export", str(log), "--out", str(tmp_path / "o"), *extra]) == 2
    assert message in capsys.readouterr().err
