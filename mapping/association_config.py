"""Parameters of the sample-based data association of ir-grid-mapping §4 (eq. 7-8).

Grouped by where they are read: the nodes and checks (``node_spacing_m``, ``min_loop_m``,
``cover_radius_m``, ``check_every_m``) and the window of scans weighted
(``window_m``, ``window_beams``, ``ref_lag_m``) in :mod:`mapping.scan_records`; the
spread of the sample cloud (``heading_noise_*``, ``position_noise_*``, fig. 9) in
:mod:`mapping.pose_samples`; the beam model of eq. 8 (``a_hit``, ``a_rand``, ``a_max``,
``sigma_hit_*``, ``occupied_p``, ``max_range_m``) in :mod:`mapping.beam_model`; the
tempering and the acceptance tests (``temperature``, ``max_stages``, ``mh_moves``,
``ess_max``, ``min_distinct``, ``significance_d2``, ``lr_min``, and the held-out test
``confirm_nats``, ``reject_nats``, ``confirm_min_m``, ``confirm_m``) in :mod:`mapping.loop_correction` and
:mod:`mapping.pose_samples`; the bounded re-insertion (``reinsert_m``,
``snapshot_every_m``, ``reinsert_per_step``) and the lost heading (``lost_heading_rad``:
3 sigma of the heading since the last correction beyond which no check runs) in
:mod:`mapping.association`; the drift hypotheses (``drift_sigma_per_rad``: the prior
sigma of the input heading's error per radian turned, the gyro's scale sigma, 0 = no
test; ``drift_steps``: the hypotheses in units of the current spacing) in
:mod:`mapping.heading_drift`; the pose graph solved at the end of a run (``pose_graph``
on or off, ``graph_node_m``: a node per this much travel, ``graph_scale_sigma`` and
``graph_scale_length_m``: the wheels' distance scale error and the length over which it
persists) in :mod:`mapping.loop_graph`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class AssociationConfig:
    """Parameters of sample-based data association (defaults: the simulated Pioneer)."""

    samples: int = 200
    node_spacing_m: float = 2.0
    min_loop_m: float = 8.0
    cover_radius_m: float = 1.0
    check_every_m: float = 0.5
    window_m: float = 1.5
    window_beams: int = 48
    ref_lag_m: float = 3.0
    heading_noise_rad_per_sqrt_m: float = 0.0
    heading_noise_per_sqrt_rad: float = 0.0
    position_noise_m_per_sqrt_m: float = 0.02
    a_hit: float = 0.75
    a_rand: float = 0.2
    a_max: float = 0.05
    sigma_hit_m: float = 0.2
    sigma_hit_per_m2: float = 0.01
    occupied_p: float = 0.65
    temperature: float = 4.0
    max_stages: int = 12
    mh_moves: int = 2
    ess_max: float = 0.5
    min_distinct: int = 40
    significance_d2: float = 11.34
    lr_min: float = 5.67
    confirm_nats: float = 6.9
    reject_nats: float = -2.3
    confirm_min_m: float = 1.5
    confirm_m: float = 3.0
    reinsert_m: float = 12.0
    snapshot_every_m: float = 3.0
    reinsert_per_step: int = 10
    lost_heading_rad: float = math.pi / 2
    max_range_m: float = 5.5
    drift_sigma_per_rad: float = 0.005
    drift_steps: tuple[float, ...] = (-3.0, -1.5, 1.5, 3.0)
    pose_graph: bool = True
    graph_node_m: float = 1.0
    graph_scale_sigma: float = 0.03
    graph_scale_length_m: float = 10.0

    def __post_init__(self) -> None:
        if self.samples < 10:
            raise ValueError("association samples must be >= 10")
        for name in ("node_spacing_m", "check_every_m", "window_m", "temperature",
                     "confirm_m", "reinsert_m", "snapshot_every_m", "graph_node_m",
                     "graph_scale_length_m"):  # fmt: skip
            if getattr(self, name) <= 0:
                raise ValueError(f"association {name} must be > 0")
        if self.min_loop_m < self.ref_lag_m:
            raise ValueError(
                "association min_loop_m must be >= ref_lag_m (a node must lie in the "
                "map matched against)"
            )
        if self.reject_nats >= 0 or self.confirm_nats <= 0:
            raise ValueError("association needs reject_nats < 0 < confirm_nats")
        if not 0 <= self.confirm_min_m <= self.confirm_m:
            raise ValueError("association needs 0 <= confirm_min_m <= confirm_m")
        if self.window_beams < 1:
            raise ValueError("association window_beams must be >= 1")
        if self.reinsert_per_step < 1:
            raise ValueError("association reinsert_per_step must be >= 1")
        if self.max_stages < 1 or self.mh_moves < 0 or not 0 < self.min_distinct <= self.samples:
            raise ValueError("association needs max_stages >= 1, mh_moves >= 0 and "
                             "0 < min_distinct <= samples")  # fmt: skip
        if not (math.isfinite(self.drift_sigma_per_rad) and self.drift_sigma_per_rad >= 0):
            raise ValueError("association drift_sigma_per_rad must be finite and >= 0")
        if any(not math.isfinite(m) or m == 0 for m in self.drift_steps):
            raise ValueError("association drift_steps must be finite and non-zero (the "
                             "null hypothesis is the association's own branch)")  # fmt: skip
        if not (math.isfinite(self.graph_scale_sigma) and self.graph_scale_sigma >= 0):
            raise ValueError("association graph_scale_sigma must be finite and >= 0")
        if abs(self.a_hit + self.a_rand + self.a_max - 1.0) > 1e-6:
            raise ValueError("association a_hit + a_rand + a_max must be 1 (eq. 8 weights)")

    def window_scans(self, mounts: int) -> int:
        """The scans of a window (at most; evenly spread over ``window_m``) for ``mounts``
        IR sensors: as many as hold about ``window_beams`` beams (8 scans of the default
        six), at least 2. The acceptance tests count the window's evidence in nats
        summed over its beams (``lr_min``, ``confirm_nats``, ``temperature`` for nearby
        beams' correlation), so a window of a fixed number of scans would weigh a
        four-sensor layout's evidence at two thirds and an eight-sensor one's at four
        thirds of what the thresholds were set for (docs/benchmarks.md: on the Intel log
        with eight sensors, a fixed 8 scans made 2 of 4 seeds worse than no association,
        48 beams none)."""
        return max(2, round(self.window_beams / max(mounts, 1)))
