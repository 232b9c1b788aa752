"""CP of a real robot (localization/cp_rb.py and its parts) on a simulated robot whose
every error respects the configured bounds (drawn inside them, seeded): the truth is
inside every reported box; the heading, unknown at the start or lost in a long gap,
narrows again from bearings; a gross outlier is voted out and named; more outliers
than q are reported (relaxed / reinit / lost), never silently; the chains and the
velocity-odometry model hold the sampled true motions.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import replace

import numpy as np

from localization.chain import leave_out, projections, relaxed_chain_at
from localization.cp_config import RangeBearingCPConfig, poly
from localization.cp_rb import RangeBearingCP
from localization.velocity_odometry import CommandIntegrator, predict_boxes

TAU = 2 * math.pi
LANDMARKS = {6 + i: (x, y, 0.0, 0.0) for i, (x, y) in enumerate(
    [(0.0, 0.0), (4.0, 0.5), (8.0, 0.0), (8.5, 4.0), (8.0, 8.0), (4.0, 8.5), (0.0, 8.0), (-0.5, 4.0)]
)}  # fmt: skip


def _check_heading_model(cfg, e, we, ve, dt) -> None:
    """The world's heading error ``e`` keeps both pair conditions (velocity_odometry)."""
    turn = np.concatenate([[0.0], np.cumsum(np.abs(we[:-1]) * dt)])
    dist = np.concatenate([[0.0], np.cumsum(np.abs(ve[:-1]) * dt)])
    for k in range(1, e.size, 7):
        d = np.abs(e[k:] - e[:-k])
        base = cfg.heading_drift_radps * k * dt + cfg.heading_drift_per_m * (dist[k:] - dist[:-k])
        tn = turn[k:] - turn[:-k]
        assert np.all(d <= cfg.heading_transient_rad + base + cfg.heading_turn_rel * tn + 1e-9)
        long = cfg.heading_transient_long_rad + base + cfg.heading_turn_rel_long * tn
        assert np.all(d <= long + 1e-9)


class World:
    """A robot driving by commands with errors inside the model's bounds (0.9 of them)."""

    def __init__(
        self, seed: int, cfg: RangeBearingCPConfig, seconds: float = 30.0, long_turns: bool = False
    ) -> None:
        rng = np.random.default_rng(seed)
        self.cfg, self.rng = cfg, rng
        dt = 0.01
        n = int(seconds / dt)
        t = np.arange(n) * dt
        # commands: 1 s segments of v in {0, 0.05, 0.086}, w in {-0.4, 0, 0.3}
        seg = (t // 1.0).astype(int)
        v = rng.choice([0.0, 0.05, 0.086], seg.max() + 1)[seg]
        w = rng.choice([-0.4, 0.0, 0.0, 0.3] if not long_turns else [0.3, 0.4], seg.max() + 1)[seg]
        self.cmd = np.column_stack([t, v, w])
        lag = cfg.command_lag_s
        i = np.clip(np.searchsorted(t, t - lag, side="right") - 1, 0, n - 1)
        we, ve = np.where(t >= lag, w[i], 0.0), np.where(t >= lag, v[i], 0.0)
        # heading error: drift at 0.85 of (b + b_m |v| + r|w|), its sign alternating every
        # 1 s (so that the long-turn bound a2 + r2 S holds too: checked below);
        # transient piecewise constant in +-0.4 a
        # long_turns: turning all the time, the drift of one sign at 0.85 of the long-turn
        # bound's r2 (the edge of the second pair condition over long spans)
        sd = np.where((t // 1.0 + rng.integers(2)) % 2 == 0, 1.0, -1.0)
        r = cfg.heading_turn_rel
        if long_turns:
            sd, r = np.full(n, rng.choice([-1.0, 1.0])), cfg.heading_turn_rel_long
        drift = np.cumsum(
            0.85
            * sd
            * (cfg.heading_drift_radps + cfg.heading_drift_per_m * np.abs(ve) + r * np.abs(we))
            * dt
        )
        trans = (
            rng.uniform(-0.4, 0.4, n // 50 + 2)[(t // 0.5).astype(int)] * cfg.heading_transient_rad
        )
        th0 = rng.uniform(-math.pi, math.pi)
        self.th = th0 + np.cumsum(we * dt) - we[0] * dt + drift + trans
        _check_heading_model(cfg, self.th - np.cumsum(we * dt), we, ve, dt)
        speed = ve * rng.uniform(
            1.0 - 0.9 * min(cfg.speed_rel_lo, 0.9), 1.0 + 0.9 * cfg.speed_rel_hi
        )
        x0, y0 = rng.uniform(2.0, 6.0, 2)
        self.x = x0 + np.concatenate([[0.0], np.cumsum(speed[:-1] * np.cos(self.th[:-1]) * dt)])
        self.y = y0 + np.concatenate([[0.0], np.cumsum(speed[:-1] * np.sin(self.th[:-1]) * dt)])
        self.t = t

    def pose(self, t: float) -> tuple[float, float, float]:
        k = int(round(t / 0.01))
        return self.x[k], self.y[k], self.th[k]

    def frame(self, t: float, max_range: float = 7.0) -> list[tuple[int, float, float]]:
        """(subject, range, bearing) of the landmarks in range, errors inside bounds."""
        c, rng = self.cfg, self.rng
        x, y, th = self.pose(t)
        common = rng.uniform(-0.9, 0.9) * c.bearing_common_rad
        out = []
        for s, (lx, ly, _, _) in LANDMARKS.items():
            d = math.hypot(lx - x, ly - y)
            if d > max_range or d < 0.3:
                continue
            e = rng.uniform(-0.9, 0.9) * (c.bearing_rad + c.bearing_lateral_m / d)
            b = math.atan2(ly - y, lx - x) - th + common + e
            if c.range_model == "depth":  # the camera reports r cos(bearing measured)
                if math.cos(b) < 0.35:  # outside its field of view
                    continue
                d *= math.cos(b)
            out.append((s, _measured(c, d, rng.uniform(0.05, 0.95)), math.remainder(b, TAU)))
        return out


def _measured(c: RangeBearingCPConfig, d: float, f: float) -> float:
    """A measured range whose bounds hold ``d`` at the fraction ``f`` of their width
    (bisection: rho + lo(rho) + f (hi(rho) - lo(rho)) grows with rho)."""
    lo, hi = 0.0, 2.0 * d + 1.0
    for _ in range(60):
        rho = 0.5 * (lo + hi)
        x = rho + poly(c.range_lo_poly, rho)
        x += f * (poly(c.range_hi_poly, rho) - poly(c.range_lo_poly, rho))
        lo, hi = (rho, hi) if x < d else (lo, rho)
    return 0.5 * (lo + hi)


def _drive(world: World, cp: RangeBearingCP, period: float = 0.25, start: float = 0.5,
           gap: tuple[float, float] | None = None, extra=None) -> list[tuple[float, bool, object]]:  # fmt: skip
    """Feed commands and frames; returns (t, truth inside, box) at every frame."""
    out = []
    k = 0
    cmds = world.cmd
    for t in np.arange(start, world.t[-1] - 0.5, period):
        while k < len(cmds) and cmds[k, 0] <= t:
            cp.command(*cmds[k])
            k += 1
        if gap and gap[0] <= t < gap[1]:
            continue
        obs = [cp.landmark(t, s, r, b) for s, r, b in world.frame(t)]
        if extra is not None:
            obs += extra(cp, t)
        box = cp.observe(t, obs)
        out.append((t, box.contains(*world.pose(t)), box))
    return out


def test_truth_inside_every_box_and_heading_found_from_unknown():
    cfg = RangeBearingCPConfig()
    for seed in (1, 2):
        world = World(seed, cfg)
        cp = RangeBearingCP(cfg, LANDMARKS, 1)
        res = _drive(world, cp)
        assert all(ok for _, ok, _ in res), [t for t, ok, _ in res if not ok][:5]
        late = [b for t, _, b in res if t > 10.0]
        widths = np.array([[b.x[1] - b.x[0], b.y[1] - b.y[0], b.th[1] - b.th[0]] for b in late])
        assert np.median(widths[:, 2]) < 1.0  # the unknown heading has been found
        assert np.median(widths[:, 0] * widths[:, 1]) < 4.0
        assert not any(e == "lost" for _, e in cp.events)


def test_boxes_between_frames_hold_the_truth():
    cfg = RangeBearingCPConfig()
    world = World(3, cfg)
    cp = RangeBearingCP(cfg, LANDMARKS, 1)
    k, misses = 0, 0
    for t in np.arange(0.5, 25.0, 0.05):
        while world.cmd[k, 0] <= t:
            cp.command(*world.cmd[k])
            k += 1
        if abs(t / 0.25 - round(t / 0.25)) < 1e-9:
            cp.observe(t, [cp.landmark(t, s, r, b) for s, r, b in world.frame(t)])
        else:
            cp.advance(t)
        misses += not cp.box().contains(*world.pose(t))
    assert misses == 0


def test_long_blind_turns_keep_the_truth_with_a_narrower_heading():
    """A robot turning all the time, its heading error at the edge of the long-turn bound
    (a2 + r2 S) over a 25 s blind stretch: the boxes hold the truth, and the heading
    predicted at the stretch's end is narrower than with the short-turn bound alone."""
    cfg = RangeBearingCPConfig()
    short = replace(cfg, heading_turn_rel_long=cfg.heading_turn_rel,
                    heading_transient_long_rad=cfg.heading_transient_rad)  # fmt: skip
    widths = {}
    for name, c in (("both", cfg), ("short", short)):
        world = World(6, cfg, seconds=40.0, long_turns=True)
        cp = RangeBearingCP(c, LANDMARKS, 1)
        before = {}

        def peek(cp, t, before=before):
            if abs(t - 30.0) < 1e-9:
                cp.advance(t)
                before["box"] = cp.box()
            return []

        res = _drive(world, cp, gap=(5.0, 30.0), extra=peek)
        assert all(ok for _, ok, _ in res), name
        b = before["box"]
        x, y, th = world.pose(30.0)
        assert b.contains(x, y, th), name
        widths[name] = b.th[1] - b.th[0]
    assert widths["both"] < widths["short"] - 1.0, widths


def test_gross_outlier_is_voted_out_and_named():
    cfg = RangeBearingCPConfig()
    world = World(4, cfg)
    cp = RangeBearingCP(cfg, LANDMARKS, 1)

    def wrong(cp, t):  # at 15 s: landmark 8 seen 3 m too far and 1 rad off
        if abs(t - 15.0) < 1e-9:
            x, y, th = world.pose(t)
            lx, ly, _, _ = LANDMARKS[8]
            return [
                cp.landmark(
                    t, 8, math.hypot(lx - x, ly - y) + 3.0, math.atan2(ly - y, lx - x) - th + 1.0
                )
            ]
        return []

    res = _drive(world, cp, extra=wrong)
    assert all(ok for _, ok, _ in res)
    assert (15.0, "landmark", 8) in cp.outliers


def test_heading_lost_in_a_long_gap_recovers():
    cfg = replace(RangeBearingCPConfig(), heading_drift_radps=0.06)  # drifts more in time
    world = World(5, cfg, seconds=60.0)
    cp = RangeBearingCP(cfg, LANDMARKS, 1)
    before = {}

    def peek(cp, t):  # the box predicted just before the first frame after the gap
        if abs(t - 40.0) < 1e-9:
            cp.advance(t)
            before["box"] = cp.box()
        return []

    res = _drive(world, cp, gap=(5.0, 40.0), extra=peek)
    assert all(ok for _, ok, _ in res)
    b = before["box"]
    assert b.th[1] - b.th[0] > TAU  # 35 s of turning blind: the heading is unknown
    after = [b for t, _, b in res if t >= 40.0]
    assert np.median([b.th[1] - b.th[0] for b in after]) < 1.0


def test_more_outliers_than_q_are_reported_and_the_box_recovers():
    cfg = RangeBearingCPConfig()
    world = World(6, cfg)
    cp = RangeBearingCP(cfg, LANDMARKS, 1)

    def burst(cp, t):  # 12-13 s: three consistent lies a frame, pointing 4 m away
        if 12.0 <= t < 13.0:
            x, y, th = world.pose(t)
            out = []
            for s in (6, 7, 8):
                lx, ly, _, _ = LANDMARKS[s]
                out.append(
                    cp.landmark(
                        t, s, math.hypot(lx - x - 4, ly - y), math.atan2(ly - y, lx - x - 4) - th
                    )
                )
            return out
        return []

    res = _drive(world, cp, extra=burst)
    flagged = {e for _, e in cp.events} & {"relaxed", "reinit", "lost"}
    assert flagged, cp.events
    assert len(cp.outliers) > 0
    assert all(ok for t, ok, _ in res if t > 17.0)  # the lies have left the window


def test_integrator_follows_the_lagged_commands():
    it = CommandIntegrator(0.2, 1.0)
    for t, v, w in ((0.0, 0.1, 0.0), (1.0, 0.1, 0.5), (2.0, 0.0, -0.5), (2.5, 0.0, 0.0)):
        it.command(t, v, w)
    it.advance(0.1)
    it.take()  # before the first command acts: unknown
    it.advance(3.2)
    st = it.take()
    # no command acts before 0.2 s; then v = 0.1 until 2.2 s, w = 0.5 on [1.2, 2.2),
    # -0.5 on [2.2, 2.7)
    assert math.isclose(st.s, 0.1 * 2.0, abs_tol=1e-12)
    assert math.isclose(st.h, 0.5 - 0.25, abs_tol=1e-12)
    assert math.isclose(st.hmax, 0.5, abs_tol=1e-12) and st.hmin == 0.0
    assert math.isclose(st.turn, 0.75, abs_tol=1e-12)
    assert math.isclose(st.unknown, 0.1, abs_tol=1e-12)
    it.advance(5.0)  # the last command (2.5 s) is older than max_hold after 3.7 s
    assert math.isclose(it.take().unknown, 5.0 - 3.7, abs_tol=1e-9)


def test_predicted_boxes_hold_the_true_motion():
    cfg = RangeBearingCPConfig()
    for seed in range(4):
        world = World(10 + seed, cfg, seconds=12.0)
        it = CommandIntegrator(cfg.command_lag_s, cfg.max_hold_s)
        for row in world.cmd:
            it.command(*row)
        t0 = 1.0
        it.advance(t0)
        it.take()
        x, y, th = world.pose(t0)
        theta0 = it.heading
        c = th - theta0
        box = np.array([[x, y, th, c - 0.5 * cfg.heading_transient_rad],
                        [x, y, th, c + 0.5 * cfg.heading_transient_rad]])  # fmt: skip
        for t1 in np.arange(t0 + 0.1, 11.0, 0.37):
            it.advance(t1)
            out = predict_boxes(box[None], np.array([theta0]), [it.peek()], cfg)[0]
            px, py, pth = world.pose(t1)
            assert out[0, 0] <= px <= out[1, 0] and out[0, 1] <= py <= out[1, 1], (seed, t1)
            assert out[0, 2] <= pth <= out[1, 2], (seed, t1)


def test_relaxed_chain_at_and_projections_match_brute_force():
    rng = np.random.default_rng(7)
    n, m, q = 9, 14, 2
    dl = rng.normal(0, 0.3, n - 1)
    dh = dl + rng.uniform(0, 0.2, n - 1)
    at = rng.integers(0, n, m)
    ml = rng.normal(0, 1, m)
    mh = ml + rng.uniform(0.5, 3, m)
    hl, hh = np.full(n, -np.inf), np.full(n, np.inf)
    hl[3], hh[3] = -2.0, 2.5
    lo, hi = relaxed_chain_at((hl, hh), (ml, mh), at, (dl, dh), q)
    p_lo, p_hi = projections((ml, mh), at, (dl, dh))
    for k in range(n):
        proj = []
        for j in range(m):
            a, b = sorted((at[j], k))
            s_lo, s_hi = dl[a:b].sum(), dh[a:b].sum()
            proj.append(
                (ml[j] + s_lo, mh[j] + s_hi) if k >= at[j] else (ml[j] - s_hi, mh[j] - s_lo)
            )
        proj = np.array(proj)
        assert np.allclose(p_lo[:, k], proj[:, 0], atol=1e-9) and np.allclose(
            p_hi[:, k], proj[:, 1], atol=1e-9
        )
        assert np.all(p_lo[:, k] <= proj[:, 0]) and np.all(p_hi[:, k] >= proj[:, 1])
        # the relaxed bound is at most the (q+1)-th largest lower bound, and the hard box
        assert (
            lo[k] <= np.sort(proj[:, 0])[m - 1 - q] + 1e-12
            and hi[k] >= np.sort(proj[:, 1])[q] - 1e-12
        )
    hyps = np.array(list(itertools.combinations(range(m), q)))
    best = leave_out(p_lo[None], q, hyps, True)[0]
    for h, e in enumerate(hyps):
        keep = [j for j in range(m) if j not in e]
        assert np.array_equal(best[h], p_lo[keep].max(axis=0))


def test_config_rejects_nonsense():
    for bad in ({"outliers": -1}, {"window_s": 0.0}, {"max_states": 1}, {"iterations": 0}):
        try:
            replace(RangeBearingCPConfig(), **bad)
        except ValueError:
            continue
        raise AssertionError(bad)
