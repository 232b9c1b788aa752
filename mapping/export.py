"""Map export: PGM + YAML (ROS map_server convention), PNG, and foxglove.Grid messages.

map_server convention (wiki.ros.org/map_server): the YAML names the image, the
``resolution`` (m/cell), the ``origin`` [x, y, yaw] of the lower-left pixel, ``negate``,
``occupied_thresh`` (0.65) and ``free_thresh`` (0.196), and ``mode``. A pixel value v
(0..255) means occupancy p = (255 - v) / 255 (negate 0). The image's first row is the
map's top (largest y). Written values:

- ``trinary``: occupied 0 (black), free 254 (white), unknown 205 (grey);
- ``scale``: v = round(255 * (1 - p)) for known cells, 205 for cells never observed
  (a log-odds of exactly 0).

:func:`read_map` reads both back: ``trinary`` gives -1 / 0 / 100 per cell like
map_server's OccupancyGrid; ``scale`` gives the probabilities. The YAML written is flat,
so it is written and parsed here without a YAML library.
"""

from __future__ import annotations

import struct
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mapping.grid import OccupancyGrid
from msgs.mapping import (
    NUMERIC_INT8,
    GridPose,
    GridQuaternion,
    GridTime,
    GridVector2,
    GridVector3,
    OccupancyGridMsg,
    PackedElementField,
)

OCCUPIED_THRESH = 0.65
FREE_THRESH = 0.196
UNKNOWN_VALUE = 205
FREE_VALUE = 254
OCCUPIED_VALUE = 0
MODES = ("trinary", "scale")


@dataclass(frozen=True)
class MapFile:
    """A map read back from PGM + YAML: cells with row 0 at the origin's y."""

    cells: np.ndarray  # trinary: int8 -1/0/100; scale: float probability, nan unknown
    resolution: float
    origin: tuple[float, float, float]
    mode: str
    occupied_thresh: float
    free_thresh: float
    negate: int
    image: str


def _pixels(grid: OccupancyGrid, mode: str, occ: float, free: float) -> np.ndarray:
    p = grid.probability()
    unknown = grid.logodds == 0
    if mode == "trinary":
        px = np.full(p.shape, UNKNOWN_VALUE, dtype=np.uint8)
        px[p > occ] = OCCUPIED_VALUE
        px[p < free] = FREE_VALUE
    elif mode == "scale":
        px = np.round(255.0 * (1.0 - p)).astype(np.uint8)
        px[unknown] = UNKNOWN_VALUE
    else:
        raise ValueError(f"map mode {mode!r}: choose one of {', '.join(MODES)}")
    return px[::-1]  # image row 0 = top of the map


def write_map(
    grid: OccupancyGrid,
    path: str | Path,
    mode: str = "trinary",
    occupied_thresh: float = OCCUPIED_THRESH,
    free_thresh: float = FREE_THRESH,
) -> tuple[Path, Path]:
    """Write ``path``.pgm and ``path``.yaml; returns both paths."""
    if not 0.0 <= free_thresh < occupied_thresh <= 1.0:
        raise ValueError("map thresholds need 0 <= free_thresh < occupied_thresh <= 1")
    base = Path(path)
    if base.suffix in (".pgm", ".yaml", ".yml"):
        base = base.with_suffix("")
    pgm, yml = base.with_suffix(".pgm"), base.with_suffix(".yaml")
    px = _pixels(grid, mode, occupied_thresh, free_thresh)
    rows, cols = px.shape
    pgm.write_bytes(b"P5\n%d %d\n255\n" % (cols, rows) + px.tobytes())
    yml.write_text(
        f"image: {pgm.name}\n"
        f"mode: {mode}\n"
        f"resolution: {grid.resolution!r}\n"
        f"origin: [{grid.origin[0]!r}, {grid.origin[1]!r}, 0.0]\n"
        "negate: 0\n"
        f"occupied_thresh: {occupied_thresh!r}\n"
        f"free_thresh: {free_thresh!r}\n"
    )
    return pgm, yml


def _parse_yaml(text: str, where: str) -> dict[str, str]:
    out: dict[str, str] = {}
    for n, line in enumerate(text.splitlines(), 1):
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        if ":" not in line:
            raise ValueError(f"{where}:{n}: expected 'key: value', got {line!r}")
        k, v = line.split(":", 1)
        out[k.strip()] = v.strip().strip("'\"")
    return out


def _read_pgm(path: Path) -> np.ndarray:
    data = path.read_bytes()
    tokens: list[bytes] = []
    pos = 0
    while len(tokens) < 4:
        while pos < len(data) and data[pos : pos + 1].isspace():
            pos += 1
        if data[pos : pos + 1] == b"#":
            pos = data.index(b"\n", pos) + 1
            continue
        start = pos
        while pos < len(data) and not data[pos : pos + 1].isspace():
            pos += 1
        if start == pos:
            raise ValueError(f"{path}: truncated PGM header")
        tokens.append(data[start:pos])
    if tokens[0] != b"P5":
        raise ValueError(f"{path}: not a binary PGM (P5), magic {tokens[0]!r}")
    cols, rows, maxval = (int(t) for t in tokens[1:])
    if maxval > 255:
        raise ValueError(f"{path}: 16-bit PGM not supported")
    pos += 1  # the single whitespace after maxval
    body = np.frombuffer(data, dtype=np.uint8, count=rows * cols, offset=pos)
    return body.reshape(rows, cols)


def read_map(yaml_path: str | Path) -> MapFile:
    """Read a map_server YAML and its PGM; cells are returned with row 0 at the bottom."""
    yml = Path(yaml_path)
    meta = _parse_yaml(yml.read_text(), str(yml))
    for key in ("image", "resolution", "origin"):
        if key not in meta:
            raise ValueError(f"{yml}: missing key {key!r} (map_server YAML needs it)")
    origin = [float(v) for v in meta["origin"].strip("[]").split(",")]
    if len(origin) != 3:
        raise ValueError(f"{yml}: origin must be [x, y, yaw], got {meta['origin']!r}")
    mode = meta.get("mode", "trinary")
    if mode not in MODES:
        raise ValueError(f"{yml}: mode {mode!r} not supported: use one of {', '.join(MODES)}")
    occ = float(meta.get("occupied_thresh", OCCUPIED_THRESH))
    free = float(meta.get("free_thresh", FREE_THRESH))
    negate = int(meta.get("negate", 0))
    px = _read_pgm(yml.parent / meta["image"])[::-1].astype(float)
    p = px / 255.0 if negate else (255.0 - px) / 255.0
    if mode == "trinary":
        cells = np.full(p.shape, -1, dtype=np.int8)
        cells[p > occ] = 100
        cells[p < free] = 0
    else:
        cells = np.where(px == UNKNOWN_VALUE, np.nan, p)
    return MapFile(
        cells=cells,
        resolution=float(meta["resolution"]),
        origin=(origin[0], origin[1], origin[2]),
        mode=mode,
        occupied_thresh=occ,
        free_thresh=free,
        negate=negate,
        image=meta["image"],
    )


def trinary_cells(
    grid: OccupancyGrid, occupied_thresh: float = OCCUPIED_THRESH, free_thresh: float = FREE_THRESH
) -> np.ndarray:
    """The grid as map_server would load it in trinary mode: -1 / 0 / 100."""
    t = grid.trinary(occupied_thresh, free_thresh)
    return np.where(t == 1, 100, t).astype(np.int8)


def png_bytes(image: np.ndarray) -> bytes:
    """A PNG of a uint8 image, grey (H, W) or RGB (H, W, 3); row 0 is the top."""
    img = np.asarray(image)
    if img.dtype != np.uint8 or img.ndim not in (2, 3):
        raise ValueError("png_bytes needs a uint8 (H, W) or (H, W, 3) array")
    colour = 2 if img.ndim == 3 else 0
    h, w = img.shape[:2]
    raw = b"".join(b"\x00" + img[r].tobytes() for r in range(h))

    def chunk(tag: bytes, payload: bytes) -> bytes:
        return (
            struct.pack(">I", len(payload))
            + tag
            + payload
            + struct.pack(">I", zlib.crc32(tag + payload) & 0xFFFFFFFF)
        )

    ihdr = struct.pack(">IIBBBBB", w, h, 8, colour, 0, 0, 0)
    return (
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", ihdr)
        + chunk(b"IDAT", zlib.compress(raw, 6))
        + chunk(b"IEND", b"")
    )


def write_png(grid: OccupancyGrid, path: str | Path, scale: int = 1) -> Path:
    """PNG of the grid (white free, black occupied, grey unknown), north up."""
    px = _pixels(grid, "scale", OCCUPIED_THRESH, FREE_THRESH)
    if scale > 1:
        px = np.kron(px, np.ones((scale, scale), dtype=np.uint8))
    out = Path(path)
    out.write_bytes(png_bytes(px))
    return out


def to_grid_msg(grid: OccupancyGrid, stamp_ns: int, frame_id: str = "map") -> OccupancyGridMsg:
    """The grid as a foxglove.Grid message: INT8 occupancy -1 unknown, 0..100 percent."""
    p = grid.probability()
    occ = np.round(p * 100.0).astype(np.int8)
    occ[grid.logodds == 0] = -1
    rows, cols = occ.shape
    sec, nsec = divmod(int(stamp_ns), 1_000_000_000)
    return OccupancyGridMsg(
        timestamp=GridTime(sec, nsec),
        frame_id=frame_id,
        pose=GridPose(GridVector3(grid.origin[0], grid.origin[1], 0.0), GridQuaternion()),
        column_count=cols,
        cell_size=GridVector2(grid.resolution, grid.resolution),
        row_stride=cols,
        cell_stride=1,
        fields=(PackedElementField("occupancy", 0, NUMERIC_INT8),),
        data=occ.tobytes(),
    )


def from_grid_msg(msg: OccupancyGridMsg) -> np.ndarray:
    """The INT8 occupancy cells (rows along +y) of a foxglove.Grid written by to_grid_msg."""
    if msg.cell_stride != 1 or msg.column_count <= 0 or msg.row_stride != msg.column_count:
        raise ValueError("grid message is not a packed INT8 occupancy grid")
    data = np.frombuffer(msg.data, dtype=np.int8)
    if data.size % msg.column_count:
        raise ValueError("grid message data is not a whole number of rows")
    return data.reshape(-1, msg.column_count)
