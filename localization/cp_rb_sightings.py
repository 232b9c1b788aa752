"""A camera's sightings as the intervals of the real-robot CP (``localization.cp_rb``):
a landmark, a peer seen, this robot seen by a peer, each turned into an
:class:`Observation` with the bounds of ``RangeBearingCPConfig`` (bounds, not sigmas;
docs/algorithms.md, "CP on the MRCLAM robots", derives them from the data).

- **Range.** The MRCLAM camera ranges a tube by its apparent size, so it reports the depth
  r cos(psi) along its optical axis, not the range r (``range_model = "depth"``): the
  bounds hold r cos(psi_m), psi_m the bearing measured, and the true range is within
  [rho + lo(rho), rho + hi(rho)] / cos(psi_m), lo and hi quadratics in rho (an offset, a
  scale and the depth's quantisation, which grows as rho^2; robots, whose tubes read
  farther, have their own). A bearing outside any camera's field (cos < MIN_COS)
  keeps only the lower bound. ``range_model = "range"``: the bounds hold r itself.
- **Bearing.** The bearing relative to the camera heading (the solver's per-frame
  unknown) is within bearing_rad + bearing_lateral_m / rho: a floor and a lateral error
  of the tube's image.
- **Peers.** A peer's published box is aged by its stamp (its speed bounds times the age)
  and not used for ``peer_quarantine_s`` after the peer weakened its guarantee. Seen by a
  peer: the peer's box when it saw this robot is the observer, its heading widened by
  the camera's common bearing bound (not aged: the bearing was measured from it), its
  position by this robot's motion since (speed cap times the age); if the peer sent its
  pieces (heading slices, each with its position
  box), the observation is a union: one per piece (``Observation.pieces``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from localization.cp_config import RangeBearingCPConfig, poly

_INF = np.inf
#: Depth model: a bearing whose cosine is below this gives no upper range bound.
MIN_COS = 0.1
#: Relative outward rounding of the range bounds (products of a few floats).
_ROUND = 1e-12
#: Ranges below this count as this in the bearing bound (a lateral error over range).
MIN_RANGE_M = 0.3


@dataclass(frozen=True)
class Observation:
    """One range-bearing observation as the window keeps it: the other party's box,
    range and bearing intervals, and its name."""

    t: float
    kind: str  # landmark | peer_seen | seen_by
    subject: int  # landmark or peer subject #
    own: bool  # this robot observes (else it is observed)
    other: tuple[float, float, float, float, float, float]  # x, y, th (lo, hi) of the other
    rho: tuple[float, float]
    beta: tuple[float, float]
    #: a peer's pieces (boxes like ``other``, whose hull it is): the peer lies in one of
    #: them, so the observation holds for one of them (empty: ``other`` alone)
    pieces: tuple[tuple[float, float, float, float, float, float], ...] = ()


@dataclass(frozen=True)
class PeerBox:
    """A peer's published box with its stamp, and when the peer last had to weaken its
    guarantee (relaxed, reinit or lost: its box may then be wrong)."""

    t: float
    x: tuple[float, float]
    y: tuple[float, float]
    th: tuple[float, float]
    alert_t: float = -np.inf
    #: the peer's pieces (x lo, x hi, y lo, y hi, th lo, th hi) at ``t`` whose hull is the
    #: box (a heading slice each with its own position box), if it published them
    pieces: tuple[tuple[float, float, float, float, float, float], ...] = ()


class Sightings:
    """Sightings to :class:`Observation` with the bounds of ``cfg``; ``landmarks``:
    subject -> (x, y, sd x, sd y). Refused sightings are counted in ``skipped``."""

    def __init__(
        self, cfg: RangeBearingCPConfig, landmarks: dict[int, tuple[float, float, float, float]]
    ) -> None:
        self.cfg = cfg
        self.landmarks = landmarks
        self.skipped: dict[str, int] = {}

    def _rho(self, r: float, b: float, robot: bool = False) -> tuple[float, float]:
        """The true range of a target measured at range ``r``, bearing ``b``: the
        bounds of the config hold the depth r cos(b) (``range_model = "depth"``) or the
        range itself, within [r + lo(r), r + hi(r)] (``range_lo_poly``, ...);
        ``robot``: the target is a robot (its own bounds)."""
        c = self.cfg
        lo_p, hi_p = (
            (c.robot_range_lo_poly, c.robot_range_hi_poly)
            if robot
            else (c.range_lo_poly, c.range_hi_poly)
        )
        lo = max(0.0, r + poly(lo_p, r))
        hi = r + poly(hi_p, r)
        if c.range_model == "depth":
            cb = math.cos(b)
            if cb < MIN_COS:  # outside any camera's field of view: r >= its depth only
                return lo, _INF
            lo, hi = lo / cb, hi / cb
        return max(0.0, lo * (1.0 - _ROUND)), hi * (1.0 + _ROUND)  # outward: a few roundings

    def _beta(self, b: float, r: float) -> tuple[float, float]:
        """The bearing measured ``b`` (at range ``r``) relative to the camera heading:
        within bearing_rad + bearing_lateral_m / r of it."""
        c = self.cfg
        e = c.bearing_rad + c.bearing_lateral_m / max(r, MIN_RANGE_M)
        return (b - e, b + e)

    def _valid(self, r: float, b: float) -> bool:
        ok = np.isfinite(r) and np.isfinite(b) and r >= 0.0
        if not ok:
            self.skipped["invalid_observation"] = self.skipped.get("invalid_observation", 0) + 1
        return bool(ok)

    def landmark(self, t: float, subject: int, r: float, b: float) -> Observation | None:
        """This robot sees landmark ``subject`` at range ``r``, bearing ``b``."""
        lm = self.landmarks.get(int(subject))
        if lm is None or not self._valid(r, b):
            if lm is None:
                self.skipped["unknown_landmark"] = self.skipped.get("unknown_landmark", 0) + 1
            return None
        k = self.cfg.landmark_sigmas
        lx, ly, sx, sy = lm
        other = (lx - k * sx, lx + k * sx, ly - k * sy, ly + k * sy, -_INF, _INF)
        return Observation(
            t, "landmark", int(subject), True, other, self._rho(r, b), self._beta(b, r)
        )

    def _aged(self, t: float, box: PeerBox) -> tuple[float, ...]:
        """The box widened by the peer's speed bounds times its age."""
        return _widen((*box.x, *box.y, *box.th), self._grow(t, box), 0.0)

    def _aged_pieces(self, t: float, box: PeerBox, beta_c: float, g: tuple[float, float]) -> tuple:
        if not self.cfg.peer_pieces or len(box.pieces) < 2:
            return ()
        return tuple(_widen(p, g, beta_c) for p in box.pieces)

    def _grow(self, t: float, box: PeerBox) -> tuple[float, float]:
        age = abs(t - box.t)
        return self.cfg.peer_speed_mps * age, self.cfg.peer_yaw_rate_radps * age

    def _trusted(self, t: float, box: PeerBox) -> bool:
        ok = t - box.alert_t >= self.cfg.peer_quarantine_s
        if not ok:
            self.skipped["peer_box_quarantined"] = self.skipped.get("peer_box_quarantined", 0) + 1
        return ok

    def peer_seen(
        self, t: float, peer: int, r: float, b: float, box: PeerBox
    ) -> Observation | None:
        """This robot sees ``peer``, whose last published box is ``box``."""
        if not self._valid(r, b) or not self._trusted(t, box):
            return None
        return Observation(
            t, "peer_seen", int(peer), True, self._aged(t, box), self._rho(r, b, True),
            self._beta(b, r),
        )  # fmt: skip

    def seen_by(self, t: float, peer: int, r: float, b: float, box: PeerBox) -> Observation | None:
        """``peer`` (box ``box``, with its heading) sees this robot at ``r``, ``b``: the
        peer's camera heading is its heading +- the common bearing bound. The peer's
        pieces, if it sent them (``peer_pieces``), are used rather than their hull: with
        its heading uncertain, each heading slice with its own position box puts this
        robot on a short arc, the hull on a long one (only the sightings carry pieces;
        a peer seen is a target, where its heading does not matter)."""
        if not self._valid(r, b) or not self._trusted(t, box):
            return None
        c = self.cfg
        # The box is the peer's when it saw this robot: its heading is the one the
        # bearing was measured from (not aged); this robot has moved since, at most
        # its speed cap times the age (the observer's box widened by that instead).
        g = (c.speed_cap_mps * abs(t - box.t), 0.0)
        return Observation(
            t, "seen_by", int(peer), False, _widen((*box.x, *box.y, *box.th), g,
            c.bearing_common_rad), self._rho(r, b, True), self._beta(b, r),
            self._aged_pieces(t, box, c.bearing_common_rad, g),
        )  # fmt: skip


def aged_to(box: PeerBox, t: float, cfg: RangeBearingCPConfig) -> PeerBox:
    """``box`` (and its pieces) aged to ``t`` by the peer's speed bounds, stamped ``t``."""
    age = abs(t - box.t)
    g = (cfg.peer_speed_mps * age, cfg.peer_yaw_rate_radps * age)
    w = _widen((*box.x, *box.y, *box.th), g, 0.0)
    pieces = tuple(_widen(p, g, 0.0) for p in box.pieces)
    return PeerBox(t, w[0:2], w[2:4], w[4:6], box.alert_t, pieces)


def _widen(b, g: tuple[float, float], beta_c: float) -> tuple[float, ...]:
    """A box (x lo, x hi, y lo, y hi, th lo, th hi) widened by g[0] in x, y and g[1] +
    beta_c in th."""
    gt = g[1] + beta_c
    return (b[0] - g[0], b[1] + g[0], b[2] - g[0], b[3] + g[0], b[4] - gt, b[5] + gt)
