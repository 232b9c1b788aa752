"""The typed result of an analysis: per robot, per pose source, boxes, map, diagnostics.

:class:`Analysis` holds one :class:`RobotAnalysis` per robot. The figures are plain floats
(NaN where a value could not be computed); ``None`` means "not in this log" (no CP boxes,
no map, no reference heading, ...). The JSON summary of ``hilnav analyze`` is made from
these classes in one place (report.py); the series the plots need are in
:class:`RobotSeries`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import numpy as np

    from hilnav.analysis.containment import BoxSeries
    from hilnav.analysis.errors import SourceErrors
    from hilnav.analysis.tracks import RobotLog
    from hilnav.log.reader import ReadStats
    from mapping.map_scores import MapScore
    from mapping.quality import MapQuality
    from msgs import RobotInfo


@dataclass(frozen=True)
class Stats:
    """Summary of the absolute values of a series (finite values only)."""

    mean: float
    rms: float
    p95: float
    max: float
    final: float


@dataclass(frozen=True)
class RigidFit:
    """Best rotation + translation of a whole track onto the reference."""

    dx_m: float
    dy_m: float
    dtheta_deg: float


@dataclass(frozen=True)
class PositionErrors:
    """Position error of a pose source against the reference, in metres."""

    error_m: Stats | None
    initial_m: float
    after_rigid_fit_m: Stats | None
    rigid_fit: RigidFit
    relative_10m_m: float | None = None  # the motions over 10 m of travel (truth only)


@dataclass(frozen=True)
class HeadingDrift:
    """Heading drift per metre travelled (None when the distance is 0.5 m or less)."""

    distance_m: float
    final_deg_per_m: float | None = None
    slope_deg_per_m: float | None = None


@dataclass(frozen=True)
class HeadingErrors:
    """Heading error of a pose source against the reference's heading, in degrees."""

    error_deg: Stats | None
    drift: HeadingDrift | None  # None with fewer than two finite heading errors


@dataclass(frozen=True)
class SourceTrack:
    """What one pose source (pose, heading, odometry, gyro, ...) gets right and wrong."""

    samples: int
    position: PositionErrors | None  # None for the gyro (a heading only)
    heading: HeadingErrors | None  # None without a reference heading (GPS reference)
    aligned_at_start: bool  # dead reckoning, aligned to the reference at its first sample


@dataclass(frozen=True)
class EkfContainment:
    """Fraction of pose estimates whose 3-sigma bounds hold the truth."""

    poses: int
    contained_fraction: float


@dataclass(frozen=True)
class BoxContainment:
    """How many CP boxes were judged against the truth, how many held it, and the median
    area of those judged (the boxes in a gap of the truth left out)."""

    judged: int
    contained_fraction: float
    violations: int
    median_area_m2: float = float("nan")


@dataclass(frozen=True)
class BoxSummary:
    """The CP pose boxes of a robot: count, areas, heading widths, containment."""

    boxes: int
    empty_boxes: int
    area_m2: Stats | None
    median_area_m2: float
    theta_width_deg: Stats | None
    containment: BoxContainment | None  # None without truth


@dataclass(frozen=True)
class MapSummary:
    """The last occupancy grid, and its quality against the floor plan when one is named."""

    maps_logged: int
    rows: int
    cols: int
    resolution_m: float
    known_cells: int
    occupied_cells: int
    plan: str | None = None
    plan_error: str | None = None  # the plan named could not be loaded
    quality: MapQuality | None = None
    scores: MapScore | None = None  # against the plan or the log's reference map
    scored_against: str | None = None  # "plan" or "reference_map"

    @property
    def match_ratio(self) -> float | None:
        return self.quality.match_ratio if self.quality is not None else None


@dataclass(frozen=True)
class TruthGaps:
    """Gaps of the truth (a data set's motion capture lost the robot): not scored."""

    count: int
    total_s: float
    longest_s: float


@dataclass(frozen=True)
class HeadingConsistency:
    """The heading filter's variance against the reference heading (NEES)."""

    samples: int
    mean_nees: float  # 1 for a consistent filter
    within_99_fraction: float  # NEES <= chi2(1) 99 %: about 0.99 when consistent
    final_sigma_deg: float
    final_error_deg: float
    max_error_deg: float
    lost: bool  # 3 sigma >= 90 deg at the end: the filter says its heading is lost


@dataclass(frozen=True)
class AssociationSummary:
    """What the data association did: checks by outcome, and the reasons given."""

    checks: int
    outcomes: dict[str, int]
    reasons: dict[str, int]  # reason (numbers stripped) -> count


@dataclass(frozen=True)
class LandmarkSummary:
    """Landmark maps logged, and the landmarks in the last one."""

    maps_logged: int
    count: int


@dataclass(frozen=True)
class DeviceSummary:
    """A device's diagnostics: its last counters, connection and rate, distinct errors."""

    reports: int
    connected_fraction: float
    frames_ok: int
    bad_checksums: int
    resyncs: int
    bytes_skipped: int
    frames_lost: int
    reconnects: int
    mean_rate_hz: float
    errors: list[str]
    malformed: int = 0
    duplicates: int = 0


@dataclass(frozen=True)
class GpsFixes:
    """The GPS fixes of a GPS reference, and how many the outlier rule excluded."""

    fixes: int
    excluded: int
    travelled_from: str | None  # "controls", "odometry"; None: no rule (nothing to judge by)


@dataclass
class RobotSeries:
    """The series behind the figures, for the plots."""

    log: RobotLog
    errors: dict[str, SourceErrors]
    boxes: BoxSeries | None
    gps_keep: np.ndarray | None = None  # fixes kept by the GPS outlier rule (time order)


@dataclass
class RobotAnalysis:
    """Everything the log tells about one robot."""

    name: str
    reference: str  # "truth", "gps" or "none"
    topics: dict[str, int]
    series: RobotSeries
    reference_distance_m: float | None = None
    gps_fixes: GpsFixes | None = None  # with a GPS reference
    truth_gaps: TruthGaps | None = None  # a truth with gaps
    paths: dict[str, SourceTrack] = field(default_factory=dict)
    ekf_3sigma: dict[str, EkfContainment] = field(default_factory=dict)
    cp_boxes: BoxSummary | None = None
    map: MapSummary | None = None
    heading_consistency: HeadingConsistency | None = None
    association: AssociationSummary | None = None
    landmarks: LandmarkSummary | None = None
    diagnostics: dict[str, DeviceSummary] = field(default_factory=dict)
    info: RobotInfo | None = None


@dataclass
class Analysis:
    """The analysis of one log: what reading it saw, and each robot's figures."""

    log: str
    metadata: dict[str, str]
    read: ReadStats
    robots: dict[str, RobotAnalysis]
    plan_name: str | None  # floor plan of the map match ratio (--plan, else the log's)
    duration_s: float | None = None  # span of the robots' pose stamps
