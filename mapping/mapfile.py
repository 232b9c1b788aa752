"""Map files for ROS 2 nav2's map_server: image + YAML, written and read by nav2's rules.

The rules are those of nav2_map_server's ``map_io.cpp`` (``loadMapYaml``,
``loadMapFromFile``), followed exactly:

- **YAML** keys ``image`` (non-empty; relative to the YAML's folder unless absolute),
  ``resolution`` (m/cell), ``origin`` ([x, y, yaw] of the lower-left pixel, exactly three
  numbers), ``free_thresh``, ``occupied_thresh`` and ``negate`` (an int or a bool: ``0``,
  ``false`` ...) are required; ``mode`` is optional: ``trinary`` (default), ``scale`` or
  ``raw``. Any YAML layout is accepted (flow or block lists, comments, quotes).
- **Pixels.** ``shade`` is the mean of the R, G, B channels over 255 (a grey image: its
  value over 255); in ``trinary`` mode an image *with* an alpha channel also averages the
  alpha in. ``occ = shade`` with ``negate``, else ``1 - shade``.
- ``trinary``: ``occ > occupied_thresh`` -> 100, ``occ < free_thresh`` -> 0, else -1
  (unknown).
- ``scale``: a pixel that is not fully opaque -> -1 (unknown); else 100 / 0 as trinary,
  and in between ``rint((occ - free) / (occupied - free) * 100)``. An image without alpha
  therefore has **no** unknown cells in scale mode: never-observed cells must be
  transparent, which PGM cannot be. Scale maps are written as RGBA PNG (as nav2's
  map_saver does).
- ``raw``: ``v = round(shade * 255)``; 0..100 is the cell's value, anything else -1.
- The image's first row is the map's top row (largest y).

:func:`write_map` writes ``trinary`` and ``raw`` maps as 8-bit PGM (P5) and ``scale`` maps
as RGBA PNG, choosing every pixel so that nav2 loads each cell into the class it has here:
occupied (p > occupied_thresh), free (p < free_thresh), unknown (never observed; in
trinary also the cells in between) or, in scale mode, an in-between value 1..99. The YAML is
written with PyYAML, images with Pillow. :func:`read_map` loads a map as nav2 does and
returns the nav_msgs/OccupancyGrid cells (-1, 0..100) nav2 would publish.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from PIL import Image

from mapping.export import occupancy_probability
from mapping.grid import OccupancyGrid
from msgs.mapping import OccupancyGridMsg

OCCUPIED_THRESH = 0.65
FREE_THRESH = 0.196
UNKNOWN_VALUE = 205
FREE_VALUE = 254
OCCUPIED_VALUE = 0
MODES = ("trinary", "scale", "raw")
REQUIRED_KEYS = ("image", "resolution", "origin", "negate", "occupied_thresh", "free_thresh")
# Cell classes of a map: what must survive a round trip through nav2.
UNKNOWN, FREE, OCCUPIED, BETWEEN = -1, 0, 100, 50


@dataclass(frozen=True)
class MapFile:
    """A map as nav2's map_server loads it: nav_msgs cells with row 0 at the origin's y."""

    cells: np.ndarray  # int8: -1 unknown, 0..100
    resolution: float
    origin: tuple[float, float, float]
    mode: str
    occupied_thresh: float
    free_thresh: float
    negate: bool
    image: str


def nav2_cells(
    shade: np.ndarray,
    opaque: np.ndarray | None,
    mode: str,
    occupied_thresh: float,
    free_thresh: float,
    negate: bool = False,
) -> np.ndarray:
    """nav2's cell values (int8) of pixels of brightness ``shade`` (0..1, already averaged
    over the channels nav2 averages) and opacity ``opaque`` (None: no alpha channel)."""
    occ = shade if negate else 1.0 - shade
    out = np.full(shade.shape, -1, dtype=np.int8)
    if mode == "raw":
        v = np.round(shade * 255.0)
        ok = (v >= 0) & (v <= 100)
        out[ok] = v[ok].astype(np.int8)
        return out
    if mode not in MODES:
        raise ValueError(f"map mode {mode!r}: choose one of {', '.join(MODES)}")
    is_occ, is_free = occupied_thresh < occ, occ < free_thresh
    out[is_occ] = 100
    out[is_free & ~is_occ] = 0
    if mode == "scale":
        mid = ~is_occ & ~is_free
        scaled = np.rint((occ - free_thresh) / (occupied_thresh - free_thresh) * 100.0)
        out[mid] = scaled[mid].astype(np.int8)
        if opaque is not None:
            out[~opaque] = -1
    return out


def cell_class(cells: np.ndarray) -> np.ndarray:
    """Class of nav_msgs cells: UNKNOWN (-1), FREE (0), OCCUPIED (100), else BETWEEN."""
    c = np.asarray(cells).astype(np.int16)
    return np.where((c == -1) | (c == 0) | (c == 100), c, BETWEEN).astype(np.int8)


def wanted_class(p: np.ndarray, mode: str, occupied_thresh: float, free_thresh: float):
    """The class each cell of probability ``p`` (nan: never observed) must load as."""
    out = np.full(p.shape, UNKNOWN if mode == "trinary" else BETWEEN, dtype=np.int8)
    with np.errstate(invalid="ignore"):
        out[p > occupied_thresh] = OCCUPIED
        out[p < free_thresh] = FREE
    out[np.isnan(p)] = UNKNOWN
    return out


def _snap_table(mode: str, occupied_thresh: float, free_thresh: float) -> dict[int, np.ndarray]:
    """Per class: for every grey value 0..255, the nearest grey value nav2 loads into that
    class (opaque pixels, negate 0). ValueError if the thresholds leave a class none."""
    values = np.arange(256)
    cls = cell_class(nav2_cells(values / 255.0, None, mode, occupied_thresh, free_thresh))
    table: dict[int, np.ndarray] = {}
    for c in (UNKNOWN, FREE, OCCUPIED, BETWEEN):
        ok = values[cls == c]
        if ok.size == 0:
            continue
        nearest = np.abs(values[:, None] - ok[None, :]).argmin(axis=1)
        table[c] = ok[nearest].astype(np.uint8)
    return table


def _pixels(p: np.ndarray, mode: str, occ: float, free: float) -> tuple[np.ndarray, np.ndarray]:
    """(grey, alpha) uint8 images of the cells, row 0 = the map's top."""
    want = wanted_class(p, mode, occ, free)
    known = ~np.isnan(p)
    alpha = np.full(p.shape, 255, dtype=np.uint8)
    if mode == "raw":
        grey = np.full(p.shape, 255, dtype=np.uint8)
        grey[known] = np.round(100.0 * p[known]).astype(np.uint8)
        return grey[::-1], alpha[::-1]
    ideal = np.full(p.shape, UNKNOWN_VALUE, dtype=np.int64)
    if mode == "trinary":
        ideal[want == OCCUPIED], ideal[want == FREE] = OCCUPIED_VALUE, FREE_VALUE
    else:
        ideal[known] = np.round(255.0 * (1.0 - p[known]))
    table = _snap_table(mode, occ, free)
    grey = np.full(p.shape, UNKNOWN_VALUE, dtype=np.uint8)
    for c in np.unique(want[known] if mode == "scale" else want):
        if int(c) not in table:
            raise ValueError(f"thresholds {free}..{occ} leave no {mode} pixel for class {c}")
        sel = (want == c) & (known if mode == "scale" else True)
        grey[sel] = table[int(c)][ideal[sel]]
    if mode == "scale":
        alpha[~known] = 0
    return grey[::-1], alpha[::-1]


def _source(src: OccupancyGrid | OccupancyGridMsg) -> tuple[np.ndarray, float, tuple]:
    """(probability with nan unknown, resolution, origin [x, y, yaw]) of a grid or message."""
    if isinstance(src, OccupancyGrid):
        return occupancy_probability(src), float(src.resolution), (*src.origin, 0.0)
    if src.cell_size.x != src.cell_size.y:
        raise ValueError(f"map cells are {src.cell_size.x} x {src.cell_size.y} m: not square")
    q = src.pose.orientation
    yaw = 2.0 * math.atan2(q.z, q.w)
    origin = (src.pose.position.x, src.pose.position.y, yaw)
    return occupancy_probability(src), float(src.cell_size.x), origin


def write_map(
    source: OccupancyGrid | OccupancyGridMsg,
    path: str | Path,
    mode: str = "trinary",
    occupied_thresh: float = OCCUPIED_THRESH,
    free_thresh: float = FREE_THRESH,
) -> tuple[Path, Path]:
    """Write ``path``.pgm (trinary, raw) or ``path``.png (scale) and ``path``.yaml."""
    if mode not in MODES:
        raise ValueError(f"map mode {mode!r}: choose one of {', '.join(MODES)}")
    if not 0.0 <= free_thresh < occupied_thresh <= 1.0:
        raise ValueError("map thresholds need 0 <= free_thresh < occupied_thresh <= 1")
    p, resolution, origin = _source(source)
    base = Path(path)
    if base.suffix in (".pgm", ".png", ".yaml", ".yml"):
        base = base.with_suffix("")
    image = base.with_suffix(".png" if mode == "scale" else ".pgm")
    yml = base.with_suffix(".yaml")
    grey, alpha = _pixels(p, mode, occupied_thresh, free_thresh)
    if mode == "scale":  # RGBA, as nav2's map_saver writes scale maps (TrueColorMatte)
        rgba = np.dstack([grey, grey, grey, alpha])
        Image.fromarray(rgba, "RGBA").save(image, format="PNG")
    else:
        Image.fromarray(grey, "L").save(image, format="PPM")  # 8-bit binary PGM (P5)
    meta = {
        "image": image.name,
        "mode": mode,
        "resolution": resolution,
        "origin": [float(v) for v in origin],
        "negate": 0,
        "occupied_thresh": float(occupied_thresh),
        "free_thresh": float(free_thresh),
    }
    yml.write_text(yaml.safe_dump(meta, sort_keys=False, default_flow_style=None))
    return image, yml


def _number(meta: dict[str, Any], key: str, where: str) -> float:
    v = meta[key]
    if isinstance(v, bool) or not isinstance(v, int | float):
        raise ValueError(f"{where}: {key} must be a number, got {v!r}")
    return float(v)


def _parse_yaml(yml: Path) -> dict[str, Any]:
    """The map YAML checked as nav2's loadMapYaml checks it."""
    try:
        meta = yaml.safe_load(yml.read_text())
    except yaml.YAMLError as exc:
        raise ValueError(f"{yml}: not valid YAML: {exc}") from None
    if not isinstance(meta, dict):
        raise ValueError(f"{yml}: a map YAML is a mapping of keys, got {type(meta).__name__}")
    for key in REQUIRED_KEYS:
        if key not in meta:
            raise ValueError(f"{yml}: missing key {key!r} (nav2's map_server requires it)")
    if not isinstance(meta["image"], str) or not meta["image"]:
        raise ValueError(f"{yml}: image must name the image file, got {meta['image']!r}")
    origin = meta["origin"]
    if not isinstance(origin, list) or len(origin) != 3:
        raise ValueError(f"{yml}: origin must be [x, y, yaw] (3 numbers), got {origin!r}")
    mode = meta.get("mode", "trinary")
    if mode not in MODES:
        raise ValueError(f"{yml}: mode {mode!r} not supported: use one of {', '.join(MODES)}")
    if not isinstance(meta["negate"], int):  # bool is an int too: 0, 1, false, true
        raise ValueError(f"{yml}: negate must be 0/1 or false/true, got {meta['negate']!r}")
    return meta


def read_image(path: Path, mode: str) -> tuple[np.ndarray, np.ndarray | None]:
    """(shade 0..1 averaged as nav2 does in ``mode``, opacity mask or None) of an image."""
    with Image.open(path) as img:
        img.load()
        if img.mode in ("I;16", "I;16B", "I;16L", "I"):  # 16-bit grey (PGM maxval > 255)
            return np.asarray(img, dtype=np.float64) / 65535.0, None
        has_alpha = img.mode in ("LA", "PA", "RGBA") or "transparency" in img.info
        rgba = np.asarray(img.convert("RGBA"), dtype=np.float64)
    channels = [rgba[..., 0], rgba[..., 1], rgba[..., 2]]
    if mode == "trinary" and has_alpha:
        channels.append(rgba[..., 3])
    shade = np.mean(channels, axis=0) / 255.0
    return shade, (rgba[..., 3] == 255) if has_alpha else None


def read_map(yaml_path: str | Path) -> MapFile:
    """Load a map YAML and its image as nav2's map_server does (module docstring)."""
    yml = Path(yaml_path)
    meta = _parse_yaml(yml)
    where = str(yml)
    mode = meta.get("mode", "trinary")
    occ = _number(meta, "occupied_thresh", where)
    free = _number(meta, "free_thresh", where)
    origin = tuple(_number({"v": v}, "v", f"{where}: origin") for v in meta["origin"])
    image = Path(meta["image"])
    shade, opaque = read_image(image if image.is_absolute() else yml.parent / image, mode)
    negate = bool(meta["negate"])
    cells = nav2_cells(shade, opaque, mode, occ, free, negate)[::-1]
    return MapFile(
        cells=np.ascontiguousarray(cells),
        resolution=_number(meta, "resolution", where),
        origin=(origin[0], origin[1], origin[2]),
        mode=mode,
        occupied_thresh=occ,
        free_thresh=free,
        negate=negate,
        image=meta["image"],
    )
