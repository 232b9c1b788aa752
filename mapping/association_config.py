"""Parameters of the sample-based data association of ir-grid-mapping §4 (eq. 7-8).

Grouped by where they are read: the nodes and checks (``node_spacing_m``, ``min_loop_m``,
``cover_radius_m``, ``check_every_m``) and the window of scans weighted
(``window_m``, ``window_scans``, ``ref_lag_m``) in :mod:`mapping.scan_records`; the
spread of the sample cloud (``heading_noise_*``, ``position_noise_*``, fig. 9) in
:mod:`mapping.pose_samples`; the beam model of eq. 8 (``a_hit``, ``a_rand``, ``a_max``,
``sigma_hit_*``, ``occupied_p``, ``max_range_m``) in :mod:`mapping.beam_model`; the
tempering and the acceptance tests (``temperature``, ``refine_rounds``, ``ess_max``,
``lr_min``, ``significance_d2``) in :mod:`mapping.loop_correction`.
"""

from __future__ import annotations

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
    window_scans: int = 8
    ref_lag_m: float = 3.0
    heading_noise_rad_per_sqrt_m: float = 0.025
    heading_noise_per_sqrt_rad: float = 0.03
    position_noise_m_per_sqrt_m: float = 0.02
    a_hit: float = 0.75
    a_rand: float = 0.2
    a_max: float = 0.05
    sigma_hit_m: float = 0.2
    sigma_hit_per_m2: float = 0.01
    occupied_p: float = 0.65
    temperature: float = 4.0
    refine_rounds: int = 3
    ess_max: float = 0.5
    lr_min: float = 2.0
    significance_d2: float = 11.34
    max_range_m: float = 5.5

    def __post_init__(self) -> None:
        if self.samples < 10:
            raise ValueError("association samples must be >= 10")
        for name in ("node_spacing_m", "check_every_m", "window_m", "temperature"):
            if getattr(self, name) <= 0:
                raise ValueError(f"association {name} must be > 0")
        if self.min_loop_m < self.ref_lag_m:
            raise ValueError(
                "association min_loop_m must be >= ref_lag_m (a node must lie in the "
                "map matched against)"
            )
        if abs(self.a_hit + self.a_rand + self.a_max - 1.0) > 1e-6:
            raise ValueError("association a_hit + a_rand + a_max must be 1 (eq. 8 weights)")
