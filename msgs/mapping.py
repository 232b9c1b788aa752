"""Messages of the mapping services: the occupancy grid (as foxglove.Grid) and the
diagnostics of sample-based data association (ir-grid-mapping.txt §4).

:class:`OccupancyGridMsg` has exactly the fields of Foxglove's ``foxglove.Grid`` JSON
schema (timestamp {sec, nsec}, frame_id, pose, column_count, cell_size, row_stride,
cell_stride, fields, data as base64), so the Foxglove app draws a logged map without a
plugin. Cells are one INT8 field ``occupancy`` in the nav_msgs/OccupancyGrid convention:
-1 unknown, 0..100 occupancy probability in percent; rows run along +y from the grid's
corner at ``pose``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

# foxglove.NumericType values (PackedElementField.type).
NUMERIC_UINT8 = 1
NUMERIC_INT8 = 2
NUMERIC_FLOAT32 = 7


@dataclass(frozen=True, slots=True)
class GridTime:
    """A Foxglove time: whole seconds and nanoseconds."""

    sec: int = 0
    nsec: int = 0


@dataclass(frozen=True, slots=True)
class GridVector2:
    x: float = 0.0
    y: float = 0.0


@dataclass(frozen=True, slots=True)
class GridVector3:
    x: float = 0.0
    y: float = 0.0
    z: float = 0.0


@dataclass(frozen=True, slots=True)
class GridQuaternion:
    x: float = 0.0
    y: float = 0.0
    z: float = 0.0
    w: float = 1.0


@dataclass(frozen=True, slots=True)
class GridPose:
    """Position and orientation of the grid's corner in ``frame_id``."""

    position: GridVector3 = field(default_factory=GridVector3)
    orientation: GridQuaternion = field(default_factory=GridQuaternion)


@dataclass(frozen=True, slots=True)
class PackedElementField:
    """One field of a grid cell: name, byte offset in the cell, foxglove.NumericType."""

    name: str
    offset: int
    type: int


@dataclass(frozen=True, slots=True)
class OccupancyGridMsg:
    """An occupancy grid as a foxglove.Grid (INT8 occupancy: -1 unknown, 0..100 %)."""

    SCHEMA_NAME: ClassVar[str] = "foxglove.Grid"

    timestamp: GridTime
    frame_id: str
    pose: GridPose
    column_count: int
    cell_size: GridVector2
    row_stride: int
    cell_stride: int
    fields: tuple[PackedElementField, ...]
    data: bytes


@dataclass(frozen=True, slots=True)
class AssociationReport:
    """What sample-based data association did at one check (ir-grid-mapping eq. 7-8).

    outcome: "accepted" (pose corrected, the range data of the re-insertion window
    re-aligned and re-inserted), "drift" (a drift of the input heading per radian turned
    adopted: the poses since its test began re-aligned, every later step corrected;
    node_index -1, ess_fraction 0, log_likelihood_ratio the test's evidence),
    "unconfirmed" (a candidate correction the later scans did not confirm: kept the
    uncorrected branch), "confirmed" (evidence agrees with the uncorrected pose), "weak"
    (evidence too flat, or a posterior resting on too few samples: the uncorrected branch
    is kept), "worse" (the corrected pose explains the window no better than the
    uncorrected one: kept). ess_fraction is the effective sample size over the sample
    count of the whole evidence on the prior cloud; log_likelihood_ratio compares the
    corrected and uncorrected poses on the window (nats,
    tempered); reason says why, with the held-out test's figures.
    """

    stamp_ns: int
    outcome: str
    node_index: int
    samples: int
    ess_fraction: float
    log_likelihood_ratio: float
    correction_x_m: float = 0.0
    correction_y_m: float = 0.0
    correction_theta_rad: float = 0.0
    realigned_scans: int = 0
    reason: str = ""
