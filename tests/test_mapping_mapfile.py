"""Map files for nav2: every cell's class survives a round trip through nav2's loading rules.

``nav2_load`` below is written again from nav2_map_server's map_io.cpp (loadMapYaml and
loadMapFromFile), pixel by pixel, independently of mapping.mapfile: the YAML keys it
requires, the shade averaged over R, G, B (and alpha in trinary mode when the image has
one), negate, the thresholds, scale mode's transparency for unknown, raw values, and the
bottom-up rows.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from PIL import Image

from mapping.export import to_grid_msg
from mapping.grid import OccupancyGrid
from mapping.mapfile import read_map, write_map


def nav2_load(yaml_path: Path) -> dict:
    """What nav2's map_server publishes for a map YAML: info and int8 cells (row 0 bottom)."""
    doc = yaml.safe_load(yaml_path.read_text())
    image = doc["image"]
    assert isinstance(image, str) and image, "The image tag was empty."
    if not image.startswith("/"):
        image = str(yaml_path.parent / image)
    origin = [float(v) for v in doc["origin"]]
    assert len(origin) == 3
    free_t, occ_t = float(doc["free_thresh"]), float(doc["occupied_thresh"])
    mode = doc.get("mode", "trinary")  # optional
    assert mode in ("trinary", "scale", "raw")
    negate = doc["negate"]  # yaml-cpp: as<int>, else as<bool>
    assert isinstance(negate, int)
    img = Image.open(image)
    matte = img.mode in ("LA", "PA", "RGBA") or "transparency" in img.info
    pixels = img.convert("RGBA")
    width, height = img.size
    data = np.zeros((height, width), dtype=np.int8)
    for y in range(height):
        for x in range(width):
            r, g, b, a = pixels.getpixel((x, y))
            channels = [r, g, b]
            if mode == "trinary" and matte:
                channels.append(a)  # MaxRGB - opacity: the alpha, 255 opaque
            shade = sum(channels) / len(channels) / 255.0
            occ = shade if negate else 1.0 - shade
            if mode == "raw":
                v = math.floor(shade * 255.0 + 0.5)  # std::round
                cell = v if 0 <= v <= 100 else -1
            elif mode == "scale" and a != 255:
                cell = -1
            elif occ_t < occ:
                cell = 100
            elif occ < free_t:
                cell = 0
            elif mode == "trinary":
                cell = -1
            else:
                cell = round((occ - free_t) / (occ_t - free_t) * 100.0)  # std::rint
            data[height - y - 1, x] = cell
    return {"resolution": float(doc["resolution"]), "origin": origin, "cells": data}


def _grid(seed: int = 0, shape: tuple[int, int] = (23, 31)) -> OccupancyGrid:
    rng = np.random.default_rng(seed)
    lo = rng.uniform(-4, 4, shape).astype(np.float32)
    lo[rng.random(shape) < 0.3] = 0.0  # never observed
    # Cells right at and around the thresholds, where rounding could move a class.
    p_edges = np.array([0.196, 0.1961, 0.25, 0.2501, 0.65, 0.6501, 0.649, 0.195, 0.5001])
    edge = np.log(p_edges) - np.log1p(-p_edges)
    lo.flat[: edge.size] = edge
    return OccupancyGrid.from_array(lo, 0.05, (-1.25, 2.5))


def _classes(p: np.ndarray, mode: str, occ: float, free: float) -> np.ndarray:
    """The class each cell must load as: -1 unknown, 0 free, 100 occupied, 50 between."""
    out = np.full(p.shape, -1 if mode == "trinary" else 50)
    out[p > occ] = 100
    out[p < free] = 0
    out[np.isnan(p)] = -1
    return out


def _loaded_classes(cells: np.ndarray) -> np.ndarray:
    c = cells.astype(int)
    return np.where((c == -1) | (c == 0) | (c == 100), c, 50)


def _p(g: OccupancyGrid) -> np.ndarray:
    return np.where(g.logodds == 0, np.nan, g.probability())


@pytest.mark.parametrize("mode", ["trinary", "scale"])
@pytest.mark.parametrize(("occ", "free"), [(0.65, 0.196), (0.65, 0.25), (0.9, 0.1)])
def test_every_cell_class_round_trips_through_nav2(tmp_path, mode, occ, free):
    g = _grid()
    image, yml = write_map(g, tmp_path / "room", mode=mode, occupied_thresh=occ, free_thresh=free)
    assert image.suffix == (".png" if mode == "scale" else ".pgm")
    nav2 = nav2_load(yml)
    want = _classes(_p(g), mode, occ, free)
    assert np.array_equal(_loaded_classes(nav2["cells"]), want)
    assert nav2["resolution"] == 0.05 and nav2["origin"] == [-1.25, 2.5, 0.0]
    assert {-1, 0, 100} <= set(np.unique(want).tolist())
    back = read_map(yml)  # the library's loader gives nav2's cells too
    assert np.array_equal(back.cells, nav2["cells"])
    assert (back.mode, back.occupied_thresh, back.free_thresh, back.negate) == (
        mode, occ, free, False)  # fmt: skip


def test_trinary_pgm_pixels_are_map_servers(tmp_path):
    g = _grid(1)
    pgm, _ = write_map(g, tmp_path / "m")
    raw = pgm.read_bytes()
    header = b"P5\n31 23\n255\n"
    assert raw.startswith(header)
    px = np.frombuffer(raw[len(header) :], dtype=np.uint8).reshape(23, 31)
    assert set(np.unique(px).tolist()) <= {0, 205, 254}  # occupied, unknown, free
    assert (
        px[0, 0] == {100: 0, 0: 254, -1: 205}[int(_classes(_p(g), "trinary", 0.65, 0.196)[-1, 0])]
    )


def test_scale_maps_need_alpha_for_unknown(tmp_path):
    """Scale mode without transparency (a PGM) loads never-observed cells as known."""
    g = _grid(2)
    png, yml = write_map(g, tmp_path / "s", mode="scale")
    assert Image.open(png).mode == "RGBA"
    unknown = g.logodds == 0
    assert np.all(nav2_load(yml)["cells"][unknown] == -1)
    grey = np.asarray(Image.open(png).convert("L"))
    Image.fromarray(grey, "L").save(tmp_path / "s.pgm", format="PPM")
    doc = yaml.safe_load(yml.read_text()) | {"image": "s.pgm"}
    (tmp_path / "pgm.yaml").write_text(yaml.safe_dump(doc))
    assert not np.any(nav2_load(tmp_path / "pgm.yaml")["cells"][unknown] == -1)


def test_raw_values_round_trip(tmp_path):
    g = _grid(3)
    _, yml = write_map(g, tmp_path / "r", mode="raw")
    p = _p(g)
    want = np.where(np.isnan(p), -1, np.round(np.nan_to_num(p) * 100)).astype(np.int8)
    assert np.array_equal(nav2_load(yml)["cells"], want)
    assert np.array_equal(read_map(yml).cells, want)


def test_the_logged_map_message_exports_like_the_grid(tmp_path):
    g = _grid(4)
    msg = to_grid_msg(g, 1_000)
    _, yml = write_map(msg, tmp_path / "msg")
    percent = np.where(g.logodds == 0, np.nan, np.round(g.probability() * 100) / 100)
    want = _classes(percent, "trinary", 0.65, 0.196)
    assert np.array_equal(_loaded_classes(nav2_load(yml)["cells"]), want)


def test_read_map_takes_any_valid_yaml_and_image(tmp_path):
    """negate: false, block-list origins, comments, an ASCII PGM (P2), an absolute path."""
    px = np.array([[0, 254, 205], [254, 254, 0]], dtype=np.uint8)  # top row first
    body = "\n".join(" ".join(str(v) for v in row) for row in px)
    (tmp_path / "a.pgm").write_bytes(b"P2\n# a comment\n3 2\n255\n" + body.encode() + b"\n")
    (tmp_path / "a.yaml").write_text(
        "# written by hand\n"
        f"image: '{tmp_path / 'a.pgm'}'\n"
        "resolution: 0.1\n"
        "origin:\n  - 1.0\n  - -2\n  - 0.0\n"
        "negate: false\n"
        "occupied_thresh: 0.65\n"
        "free_thresh: 0.196\n"
    )
    back = read_map(tmp_path / "a.yaml")
    assert back.origin == (1.0, -2.0, 0.0) and back.mode == "trinary" and back.negate is False
    assert back.cells.tolist() == [[0, 0, 100], [100, 0, -1]]
    assert np.array_equal(back.cells, nav2_load(tmp_path / "a.yaml")["cells"])
    negated = (tmp_path / "a.yaml").read_text().replace("negate: false", "negate: 1")
    (tmp_path / "n.yaml").write_text(negated)
    assert read_map(tmp_path / "n.yaml").cells.tolist() == [[100, 100, 0], [0, 100, 100]]
    assert np.array_equal(
        read_map(tmp_path / "n.yaml").cells, nav2_load(tmp_path / "n.yaml")["cells"]
    )


def test_bad_map_files_give_clear_errors(tmp_path):
    Image.fromarray(np.zeros((2, 2), np.uint8), "L").save(tmp_path / "z.pgm", format="PPM")
    good = {
        "image": "z.pgm", "resolution": 0.1, "origin": [0, 0, 0], "negate": 0,
        "occupied_thresh": 0.65, "free_thresh": 0.196,
    }  # fmt: skip
    for change, match in [
        ({"origin": None}, "missing key 'origin'"),
        ({"negate": None}, "missing key 'negate'"),
        ({"free_thresh": None}, "missing key 'free_thresh'"),
        ({"origin": [0, 0]}, "3 numbers"),
        ({"mode": "fancy"}, "mode"),
        ({"image": ""}, "image"),
        ({"negate": "maybe"}, "negate"),
    ]:
        doc = {k: v for k, v in (good | change).items() if v is not None}
        (tmp_path / "m.yaml").write_text(yaml.safe_dump(doc))
        with pytest.raises(ValueError, match=match):
            read_map(tmp_path / "m.yaml")
    with pytest.raises(ValueError, match="mode"):
        write_map(_grid(), tmp_path / "c", mode="fancy")
    with pytest.raises(ValueError, match="thresholds"):
        write_map(_grid(), tmp_path / "c", occupied_thresh=0.2, free_thresh=0.3)
