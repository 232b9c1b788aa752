"""Guaranteed localization of a real robot by interval constraint propagation over a
sliding window (issue 14 items 2-3): velocity odometry, range-bearing to known
landmarks, and, cooperatively, range-bearing to and from peers whose boxes arrive with
their stamps. Seconds on the data's own clock, metres, radians.

- ``localization.velocity_odometry``: the commands integrated between states, and the
  odometry's error model;
- ``localization.range_bearing``: the observation contractor;
- ``localization.cp_rb_sightings``: a camera's sightings as intervals (the bounds of
  ``RangeBearingCPConfig``: the range as a depth r cos(bearing), the bearing bound
  growing at short range, peers' boxes aged);
- ``localization.cp_rb_solve``: the window's contraction, q-relaxed over every
  observation, with the heading cut into pieces (sectors when it is unknown);
- here: :class:`RangeBearingCP`, which keeps the window (one state per observation
  instant, solved every ``solve_period_s``; the solution's heading pieces are kept, each
  with its boxes over the window, and a state leaving the window becomes the next one's
  prior, one box per piece), names the inconsistent observations, and fails
  gracefully.

**Graceful failure.** A solve that comes out empty proves that more than q observations
of the window (or a prior built from an earlier window) broke their bounds. Then, in
turn: the solve is repeated without the previous solution's boxes (status ``cold``);
then with up to ``max_extra_outliers`` more observations voted out but the prior kept
(``relaxed``: a burst of misread barcodes must not overrule what the window's past
established); then without the prior, re-initialised from the whole plane and an
unknown heading, the window's own observations only (``reinit``); if that is still
empty the robot is **lost**: the window is cleared, the box is the whole plane, and the
next observations narrow it again. Every fallback is recorded in ``events`` with its
time; the observations found inconsistent are named in ``outliers``; a box published
while ``relaxed``, ``reinit`` or ``lost`` carries only the weaker guarantee its status
says, and peers may ignore it (``last_alert``). What no fallback can catch: more than q
observations wrong in the same way and contradicted by nothing else in the window (a
misread repeated with no other landmark in view) give a consistent, wrong box. That is
the limit of the guarantee, and why q and the bounds are configuration.

Usage (time-ordered calls)::

    cp = RangeBearingCP(RangeBearingCPConfig(), landmarks={6: (x, y, sx, sy), ...})
    cp.command(t, v, w)                           # every odometry sample
    cp.observe(t, [cp.landmark(t, 7, r, b), cp.peer_seen(t, 2, r, b, peer_box), ...])
    cp.hear(3, r, b, box_of_3)                    # robot 3 saw this one (used next solve)
    cp.box() -> RBBox                             # at the latest integrated instant
    cp.advance(t); cp.box()                       # predicted to t
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from localization.cp_config import RangeBearingCPConfig
from localization.cp_rb_sightings import Observation, PeerBox, Sightings
from localization.cp_rb_solve import WindowProblem, WindowSolution, solve_window
from localization.interval_trig import TWO_PI
from localization.velocity_odometry import (
    CommandIntegrator,
    StepBounds,
    StepIntegral,
    combine,
    predict_boxes,
    predict_hulls,
    step_bounds,
)

_INF = np.inf


def _unknown() -> np.ndarray:
    return np.array([[-_INF] * 4, [_INF] * 4])


def _pieces_at(sol: WindowSolution, k: int) -> np.ndarray:
    """(B, 2, 4): x, y, th, c of state ``k`` in every piece of ``sol``."""
    return np.stack(
        [sol.px[:, :, k], sol.py[:, :, k], sol.pth[:, :, k], sol.pc[:, :, k]], -1
    ).transpose(1, 0, 2)


@dataclass(frozen=True)
class RBBox:
    """A box of a robot at time t (heading unwrapped: any 2 pi k shift of it holds)."""

    t: float
    x: tuple[float, float]
    y: tuple[float, float]
    th: tuple[float, float]
    status: str = "ok"  # ok | cold | relaxed | reinit | lost | unknown

    def contains(self, x: float, y: float, th: float) -> bool:
        """Whether the pose (heading modulo 2 pi) is inside."""
        lo, hi = self.th
        if hi - lo >= TWO_PI:
            in_th = True
        else:
            t = th + TWO_PI * np.ceil((lo - th) / TWO_PI)  # the first branch >= lo
            in_th = bool(t <= hi)
        return self.x[0] <= x <= self.x[1] and self.y[0] <= y <= self.y[1] and in_th


@dataclass
class _State:
    t: float
    theta: float  # commanded heading at t
    step: StepBounds | None  # from the previous state
    obs: list[Observation] = field(default_factory=list)
    raw: StepIntegral | None = None  # the commands' integral from the previous state


class RangeBearingCP:
    """Sliding-window CP of one robot (module doc)."""

    def __init__(
        self,
        config: RangeBearingCPConfig | None = None,
        landmarks: dict[int, tuple[float, float, float, float]] | None = None,
        robot: int = 0,
    ) -> None:
        self.cfg = config or RangeBearingCPConfig()
        self.robot = robot
        self._landmarks = dict(landmarks or {})
        self.odo = CommandIntegrator(self.cfg.command_lag_s, self.cfg.max_hold_s)
        self._states: list[_State] = []
        #: (P, 2, 4): x, y, th, c of the window's first state, per piece (a sub-paving)
        self._prior = _unknown()[None]
        self._sol: WindowSolution | None = None
        self.status = "unknown"
        self.outliers: list[tuple[float, str, int]] = []  # (t, kind, subject), each once
        self._named: set[tuple[float, str, int]] = set()
        self.events: list[tuple[float, str]] = []
        self.solves = 0
        #: when the guarantee last had to be weakened (relaxed, reinit, lost)
        self.last_alert = -_INF
        self.sightings = Sightings(self.cfg, self._landmarks)
        self.skipped = self.sightings.skipped  # sightings refused, by reason
        self._heard: list[tuple[int, float, float, PeerBox]] = []  # seen by peers, not yet used

    # -- inputs --------------------------------------------------------------------

    @property
    def landmarks(self) -> dict[int, tuple[float, float, float, float]]:
        """The known landmarks: subject -> (x, y, sigma x, sigma y)."""
        return self._landmarks

    @landmarks.setter
    def landmarks(self, marks: dict[int, tuple[float, float, float, float]]) -> None:
        """A new map (e.g. a ``landmark_map`` message): the sightings use it from now."""
        self._landmarks = dict(marks)
        self.sightings.landmarks = self._landmarks

    def command(self, t: float, v: float, w: float) -> None:
        self.odo.command(t, v, w)

    def advance(self, t: float) -> None:
        self.odo.advance(t)

    def landmark(self, t: float, subject: int, r: float, b: float) -> Observation | None:
        """This robot sees landmark ``subject`` at range ``r``, bearing ``b``."""
        return self.sightings.landmark(t, subject, r, b)

    def peer_seen(
        self, t: float, peer: int, r: float, b: float, box: PeerBox
    ) -> Observation | None:
        """This robot sees ``peer``, whose last published box is ``box``."""
        return self.sightings.peer_seen(t, peer, r, b, box)

    def seen_by(self, t: float, peer: int, r: float, b: float, box: PeerBox) -> Observation | None:
        """``peer`` (box ``box``, with its heading) sees this robot at ``r``, ``b``."""
        return self.sightings.seen_by(t, peer, r, b, box)

    def hear(self, peer: int, r: float, b: float, box: PeerBox) -> None:
        """``peer`` (box ``box``, stamped when it saw this robot: the measurement's
        instant) saw this robot at range ``r``, bearing ``b``: kept for the next :meth:`observe`, which uses it with the
        box's position widened by this robot's motion since (its heading as it was: the
        bearing was measured from it)."""
        self._heard.append((int(peer), float(r), float(b), box))

    # -- the window ----------------------------------------------------------------
    def observe(self, t: float, observations: list[Observation | None]) -> RBBox:
        """Add a state at ``t`` with ``observations`` (all stamped ``t``) and what peers
        reported since (:meth:`hear`), and solve."""
        obs = [o for o in observations if o is not None]
        heard, self._heard = self._heard, []
        for peer, r, b, box in heard:
            if t - box.t <= self.cfg.window_s:
                obs.append(self.seen_by(t, peer, r, b, box))
        obs = [o for o in obs if o is not None]
        self.odo.advance(t)
        st = self.odo.take()
        if self._states and t <= self._states[-1].t:  # same instant: join the last state
            self._states[-1].obs.extend(obs)
        else:
            step = step_bounds(st, self.cfg) if self._states else None
            self._states.append(_State(float(t), self.odo.heading, step, obs, st))
        solved = 0 if self._sol is None else self._sol.x.shape[1]
        due = self._sol is None or t - self._states[solved - 1].t >= self.cfg.solve_period_s
        if due:
            self._trim()
            self._solve()
        return self.box()

    def _trim(self) -> None:
        c, s = self.cfg, self._states
        while len(s) > c.max_states or (len(s) > 2 and s[-1].t - s[0].t > c.window_s):
            sol = self._sol
            if sol is not None and sol.x.shape[1] < 2:
                break  # state 1 not solved yet: keep state 0 until it is
            if sol is not None:
                # state 1's solved pieces hold what the window knew about state 0
                self._prior = _pieces_at(sol, 1)
                self._sol = replace(
                    sol,
                    **{
                        f: getattr(sol, f)[..., 1:]
                        for f in ("x", "y", "th", "c", "px", "py", "pth", "pc")
                    },
                )
            else:
                self._prior = _unknown()[None]
            del s[0]
            s[0].step, s[0].raw = None, None

    def _problem(self, warm: bool, prior: bool) -> WindowProblem:
        s = self._states
        n = len(s)
        theta = np.array([st.theta for st in s])
        steps = [st.step for st in s[1:]]
        arr = {
            f: np.array([getattr(b, f) for b in steps], dtype=float)
            for f in StepBounds.__dataclass_fields__
        }
        # Hard boxes (4, 2, P, n) of P pieces: the previous solution's (warm), else the
        # prior's pieces at the first state, else one unknown piece.
        sol = self._sol
        warm = warm and sol is not None
        pr = self._prior if prior else _unknown()[None]
        npc = sol.px.shape[1] if warm else pr.shape[0]
        hard = np.empty((4, 2, npc, n))
        hard[:, 0], hard[:, 1] = -_INF, _INF
        if warm:
            k = min(sol.x.shape[1], n)
            for i, v in enumerate((sol.px, sol.py, sol.pth, sol.pc)):
                hard[i, :, :, :k] = v[:, :, :k]
            if prior:  # the prior (hull of its pieces) at the first state too
                lo, hi = pr[:, 0].min(axis=0), pr[:, 1].max(axis=0)
                hard[:, 0, :, 0] = np.maximum(hard[:, 0, :, 0], lo[:, None])
                hard[:, 1, :, 0] = np.minimum(hard[:, 1, :, 0], hi[:, None])
        else:
            hard[:, :, :, 0] = pr.transpose(2, 1, 0)
        # one column per observation, or per piece of a peer's box (a group: the peer is
        # in one of its pieces, so the observation holds for one of the columns)
        obs = [(i, g, o, part) for g, (i, o) in enumerate(
            (i, o) for i, st in enumerate(s) for o in st.obs
        ) for part in (o.pieces or (o.other,))]  # fmt: skip
        m = len(obs)
        b = np.zeros((7, 2, m))
        at = np.array([i for i, _, _, _ in obs], dtype=int)
        own = np.array([o.own for _, _, o, _ in obs], dtype=bool)
        group = np.array([g for _, g, _, _ in obs], dtype=int)
        if m:
            other = np.array([part for _, _, _, part in obs]).T  # (6, m)
            rows = np.where(own, 3, 0)  # the other party: target rows AX, AY or observer rows
            cols = np.arange(m)
            b[rows, 0, cols], b[rows, 1, cols] = other[0], other[1]
            b[rows + 1, 0, cols], b[rows + 1, 1, cols] = other[2], other[3]
            nb = ~own
            b[2, 0, nb], b[2, 1, nb] = other[4, nb], other[5, nb]  # the observer's heading
            b[5] = np.array([o.rho for _, _, o, _ in obs]).T
            b[6] = np.array([o.beta for _, _, o, _ in obs]).T
        groups = None if m == 0 or group[-1] == m - 1 else group
        return WindowProblem(
            theta, arr["dc"], arr["hmin"], arr["hmax"], arr["l_lo"], arr["l_hi"],
            arr["slack"], arr["cap"], hard[0], hard[1], hard[2], hard[3], b, at, own,
            arr["dw"], groups,
        )  # fmt: skip

    def _run(self, warm: bool, prior: bool, q: int) -> WindowSolution:
        c = self.cfg
        p = self._problem(warm, prior)
        self.solves += 1
        sol = solve_window(
            p, q, 0.5 * c.heading_transient_rad, c.iterations, c.tol,
            c.bearing_common_rad, c.heading_piece_rad, c.max_pieces, c.heading_sectors,
        )  # fmt: skip
        if not sol.empty and sol.rebased:
            self._prior[:, :, 2:] = _unknown()[None, :, 2:]  # the headings' representation changed
        return sol

    def _solve(self) -> None:
        """Solve the window; on an empty result fall back in turn (module doc): without
        the previous solution's boxes ("cold"), voting out up to ``max_extra_outliers``
        more observations but keeping the prior ("relaxed"), without the prior
        ("reinit"), and else "lost"."""
        c = self.cfg
        t = self._states[-1].t
        q = c.outliers
        sol, status = self._run(True, True, q), "ok"
        if sol.empty:
            sol, status = self._run(False, True, q), "cold"
        extra = 1
        while sol.empty and extra <= c.max_extra_outliers:
            sol, status = self._run(False, True, q + extra), "relaxed"
            extra += 1
        if sol.empty:
            sol, status = self._run(False, False, q), "reinit"
            if not sol.empty:
                self._prior = _unknown()[None]
        self._name(sol)
        if sol.empty:
            self.events.append((t, "lost"))
            last = self._states[-1]
            self._states = [_State(last.t, last.theta, None, [])]
            self._prior = _unknown()[None]
            self._sol = None
            self.status = "lost"
            self.last_alert = t
            return
        if status != "ok":
            self.events.append((t, status))
        if status in ("relaxed", "reinit"):
            self.last_alert = t
        if sol.rebased:
            self.events.append((t, "rebased"))
        self._sol = sol
        self.status = status

    def _name(self, sol: WindowSolution) -> None:
        obs = [o for st in self._states for o in st.obs]
        for j in np.flatnonzero(sol.inconsistent):
            if j < len(obs):
                o = obs[j]
                key = (o.t, o.kind, o.subject)
                if key not in self._named:
                    self._named.add(key)
                    self.outliers.append(key)

    # -- outputs -------------------------------------------------------------------
    def latest(self) -> tuple[float, float, np.ndarray, StepIntegral] | None:
        """(t, commanded heading, (B, 2, 4) boxes x, y, th, c of the B pieces) of the
        latest solved state, and the commands' integral from it to the latest integrated
        instant."""
        if self._sol is None or not self._states:
            return None
        s = self._sol
        k = s.x.shape[1] - 1
        since = StepIntegral()
        for st in self._states[k + 1 :]:  # states not solved yet
            since = combine(since, st.raw)
        since = combine(since, self.odo.peek())
        return self._states[k].t, self._states[k].theta, _pieces_at(s, k), since

    def pieces(self) -> np.ndarray | None:
        """(B, 2, 3): x, y, heading of each piece of the latest solved state predicted to
        the latest integrated instant (the box is their hull); None before a solve."""
        ref = self.latest()
        if ref is None:
            return None
        _, theta0, b, st = ref
        return predict_boxes(b, np.full(b.shape[0], theta0), [st] * b.shape[0], self.cfg)

    def box(self) -> RBBox:
        """The box at the latest integrated instant (each piece of the latest solved
        state predicted, and their hull)."""
        t = self.odo.t if self.odo.t is not None else 0.0
        ref = self.latest()
        if ref is None:
            return RBBox(t, (-_INF, _INF), (-_INF, _INF), (-_INF, _INF), self.status)
        _, theta0, b, st = ref
        out = predict_hulls([b], np.array([theta0]), [st], self.cfg)
        return RBBox(
            t,
            (out[0, 0, 0], out[0, 1, 0]),
            (out[0, 0, 1], out[0, 1, 1]),
            (out[0, 0, 2], out[0, 1, 2]),
            self.status,
        )

    def snapshot(self) -> tuple[float, float, np.ndarray, StepIntegral, str, float] | None:
        """What :func:`velocity_odometry.predict_hulls` needs to compute the box at the
        latest integrated instant later, in bulk (for scoring many instants): t,
        commanded heading, the (B, 2, 4) pieces, the step since, status, last alert."""
        ref = self.latest()
        if ref is None:
            return None
        _, theta0, b, st = ref
        return (self.odo.t, theta0, b, st, self.status, self.last_alert)
