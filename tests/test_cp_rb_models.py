"""The real-robot CP's measurement intervals and its sub-paving, against sampled truths:
the camera's depth-range model (localization/cp_rb_sightings.py ``_rho``), the range-dependent
bearing bound, the distance the integrator adds up, the heading slices the window solver
cuts from the previous solve's pieces (localization/cp_rb_pieces.py), and
the hull of the pieces' predicted boxes (velocity_odometry.predict_hulls).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from localization.cp_config import RangeBearingCPConfig, poly
from localization.cp_rb_pieces import heading_pieces
from localization.cp_rb_sightings import MIN_COS, Sightings
from localization.velocity_odometry import (
    CommandIntegrator,
    StepIntegral,
    predict_boxes,
    predict_hulls,
)

TAU = 2 * math.pi
LM = {6: (2.0, 1.0, 0.0, 0.0)}


@pytest.mark.parametrize("model", ["depth", "range"])
def test_range_interval_holds_every_true_range_inside_the_bounds(model):
    cfg = replace(RangeBearingCPConfig(), range_model=model)
    cp = Sightings(cfg, LM)
    rng = np.random.default_rng(11)
    for robot in (False, True):
        lo_p, hi_p = (
            (cfg.robot_range_lo_poly, cfg.robot_range_hi_poly)
            if robot
            else (cfg.range_lo_poly, cfg.range_hi_poly)
        )
        for _ in range(3000):
            rho = rng.uniform(0.0, 9.0)  # the measurement
            b = rng.uniform(-1.4, 1.4)  # bearing measured
            # what the bounds hold (depth or range): anywhere inside them, edges too
            lo_x, hi_x = max(0.0, rho + poly(lo_p, rho)), rho + poly(hi_p, rho)
            f = rng.choice([0.0, 1.0, rng.uniform()])
            x = lo_x + f * (hi_x - lo_x)
            r = x / math.cos(b) if model == "depth" else x  # the true range
            lo, hi = cp._rho(rho, b, robot)
            assert lo <= r <= hi, (model, robot, r, b, rho, lo, hi)
            assert lo >= 0.0
            if model == "depth" and math.cos(b) < MIN_COS:
                assert hi == math.inf


def test_range_bounds_are_quadratic_and_checked():
    """The landmarks' depth interval is narrowest at mid range (offset and scale) and
    grows as rho^2 far away; polynomials whose hi falls below lo are refused."""
    cfg = RangeBearingCPConfig()
    w = [poly(cfg.range_hi_poly, r) - poly(cfg.range_lo_poly, r) for r in (1.0, 3.0, 7.0)]
    assert w[0] < w[1] < w[2]
    with pytest.raises(ValueError, match="hi below lo"):
        replace(cfg, range_hi_poly=(-0.2, 0.0, 0.0))
    with pytest.raises(ValueError, match="three finite"):
        replace(cfg, range_lo_poly=(0.0, math.nan, 0.0))


def test_bearing_bound_is_wider_at_short_range():
    cfg = RangeBearingCPConfig()
    cp = Sightings(cfg, LM)
    near, far = cp._beta(0.2, 1.0), cp._beta(0.2, 5.0)
    assert near[0] < far[0] < 0.2 < far[1] < near[1]
    assert math.isclose(far[1] - 0.2, cfg.bearing_rad + cfg.bearing_lateral_m / 5.0)
    assert np.isfinite(cp._beta(0.2, 0.0)).all()  # a zero range: the floor of MIN_RANGE_M


def test_integrator_adds_up_the_distance_driven_backwards_too():
    it = CommandIntegrator(0.0, 5.0)
    it.command(0.0, 0.1, 0.0)
    it.command(1.0, -0.05, 0.0)
    it.advance(0.0)
    it.advance(3.0)
    st = it.take()
    assert math.isclose(st.s, 0.1 - 0.1, abs_tol=1e-12)
    assert math.isclose(st.dist, 0.1 + 0.1, abs_tol=1e-12)


def _true_window(rng, n, half_a, beta_c):
    theta = np.cumsum(rng.normal(0.0, 0.3, n))
    dc = rng.uniform(0.001, 0.08, n - 1)
    c = np.cumsum(np.concatenate([[rng.uniform(-3.0, 3.0)], rng.uniform(-1, 1, n - 1) * dc]))
    th = theta + c + rng.uniform(-half_a, half_a, n)
    ph = th[-1] + rng.uniform(-beta_c, beta_c)
    return theta, dc, {"x": rng.normal(0, 3, n), "y": rng.normal(0, 3, n), "th": th, "c": c}, ph


def test_heading_slices_cover_every_point_of_the_parents():
    """heading_pieces cuts the parents' newest camera headings into slices (or sectors, when
    the heading is unknown): a point of any parent lies in some slice, all states."""
    rng = np.random.default_rng(5)
    half_a, beta_c = 0.06, 0.06
    seen_lost = seen_sliced = 0
    for _ in range(400):
        n = int(rng.integers(2, 7))
        npar = int(rng.integers(1, 6))
        theta, dc, true, ph = _true_window(rng, n, half_a, beta_c)
        i = int(rng.integers(npar))
        wide = rng.uniform() < 0.3  # some parents whose heading is (almost) unknown
        hard = {}
        for name, v in true.items():
            scale = 6.0 if wide and name in ("th", "c") else 0.4
            lo = v[None] - rng.uniform(0, scale, (npar, n))
            hi = v[None] + rng.uniform(0, scale, (npar, n))
            shift = rng.normal(0.0, 0.5, (npar, 1))
            shift[i] = 0.0
            box = np.stack([lo + shift, hi + shift])
            unknown = rng.uniform(size=(npar, n)) < 0.2
            box[0][unknown], box[1][unknown] = -np.inf, np.inf
            hard[name] = box
        hx, hy, hc, hth, hph, lost = heading_pieces(
            theta, dc, hard["x"], hard["y"], hard["th"], hard["c"],
            half_a, beta_c, 0.1, int(rng.integers(1, 8)), 24,
        )  # fmt: skip
        seen_lost += lost
        seen_sliced += not lost
        found = False
        for j in range(hx.shape[1]):
            k = math.floor((hph[1, j, -1] - ph) / TAU) if lost else 0  # ph + 2 pi k in it
            s = TAU * k
            ok = hph[0, j, -1] <= ph + s <= hph[1, j, -1]
            for box, v in (
                (hx, true["x"]),
                (hy, true["y"]),
                (hth, true["th"] + s),
                (hc, true["c"] + s),
            ):
                ok &= bool(np.all((box[0, j] <= v) & (v <= box[1, j])))
            found |= ok
        assert found, (lost, hph[:, :, -1], ph)
    assert seen_lost > 10 and seen_sliced > 100


def test_predicted_hull_of_pieces_holds_each_piece_prediction():
    cfg = RangeBearingCPConfig()
    rng = np.random.default_rng(2)
    pieces, theta0, steps = [], [], []
    for _ in range(30):
        b = int(rng.integers(1, 5))
        lo = rng.normal(0, 1, (b, 4))
        pieces.append(np.stack([lo, lo + rng.uniform(0.01, 0.5, (b, 4))], axis=1))
        theta0.append(rng.uniform(-3, 3))
        st = StepIntegral(dt=rng.uniform(0, 2))
        st.s = st.dist = 0.08 * st.dt
        st.h = st.hmax = st.turn = 0.3 * st.dt
        steps.append(st)
    hull = predict_hulls(pieces, np.array(theta0), steps, cfg)
    for i, b in enumerate(pieces):
        each = predict_boxes(b, np.full(b.shape[0], theta0[i]), [steps[i]] * b.shape[0], cfg)
        assert np.allclose(hull[i, 0], each[:, 0].min(axis=0))
        assert np.allclose(hull[i, 1], each[:, 1].max(axis=0))


def test_config_rejects_an_unknown_range_model():
    with pytest.raises(ValueError, match="range_model"):
        replace(RangeBearingCPConfig(), range_model="sonar")


def _seen_by_box(cfg, truth, peer, pieces, rho, b):
    """The box of a robot that knows nothing but that ``peer`` saw it (one solve)."""
    from localization.cp_rb import RangeBearingCP
    from localization.cp_rb_sightings import PeerBox

    hull = np.array(pieces)
    box = PeerBox(
        1.0,
        (hull[:, 0].min(), hull[:, 1].max()),
        (hull[:, 2].min(), hull[:, 3].max()),
        (hull[:, 4].min(), hull[:, 5].max()),
        pieces=tuple(map(tuple, pieces)),
    )
    cp = RangeBearingCP(cfg, {}, 1)
    cp.command(0.0, 0.0, 0.0)
    cp.hear(2, rho, b, box)
    return cp.observe(1.0, [])


def test_a_peer_seen_through_its_pieces_keeps_the_truth_and_is_tighter():
    """seen_by with the peer's pieces (a union: one observation column per piece, the
    hull of their contractions) holds every truth whose observer lies in one piece, and
    is never wider than with the pieces' hull (cp_rb_solve ``_union``). q = 0: one
    observation, which q = 1 would leave out."""
    cfg = replace(RangeBearingCPConfig(), outliers=0)
    off = replace(cfg, peer_pieces=False)
    rng = np.random.default_rng(8)
    tighter = 0
    for _ in range(40):
        peer = np.array([*rng.uniform(-3, 3, 2), rng.uniform(-math.pi, math.pi)])
        r_true = rng.uniform(0.8, 4.0)
        psi = rng.uniform(-0.5, 0.5)  # true bearing from the peer's camera
        cam = peer[2] + rng.uniform(-0.9, 0.9) * cfg.bearing_common_rad
        truth = peer[:2] + r_true * np.array([math.cos(cam + psi), math.sin(cam + psi)])
        rho = r_true * math.cos(psi) / 0.9375  # a depth reading inside the robot bounds
        lo, hi = Sightings(cfg, {})._rho(rho, psi, True)
        assert lo <= r_true <= hi
        e = 0.9 * rng.uniform(-1, 1) * (cfg.bearing_rad + cfg.bearing_lateral_m / rho)
        b = psi + e
        # the peer's pieces: heading slices of a wide heading, each with a position box
        # on an arc (the peer placed by a landmark ell ahead: turned by d, it sits
        # ell d to the side), the truth in one of them
        k = int(rng.integers(2, 6))
        w = rng.uniform(0.3, 1.5)
        ell = rng.uniform(0.5, 4.0)
        edges = peer[2] - rng.uniform(0, w) + w * np.arange(k + 1) / k
        pieces = []
        for j in range(k):
            mid = 0.5 * (edges[j] + edges[j + 1])
            c = peer[:2] - ell * (mid - peer[2]) * np.array([-math.sin(mid), math.cos(mid)])
            s = rng.uniform(0.05, 0.2)
            pieces.append([c[0] - s, c[0] + s, c[1] - s, c[1] + s, edges[j], edges[j + 1]])
        j = int(np.searchsorted(edges, peer[2]) - 1)  # the slice of the peer's heading
        pieces[j][:4] = [peer[0] - 0.1, peer[0] + 0.1, peer[1] - 0.1, peer[1] + 0.1]
        with_p = _seen_by_box(cfg, truth, peer, pieces, rho, b)
        hull = _seen_by_box(off, truth, peer, pieces, rho, b)
        for bx in (with_p, hull):
            assert bx.x[0] <= truth[0] <= bx.x[1] and bx.y[0] <= truth[1] <= bx.y[1]
        assert hull.x[0] - 1e-9 <= with_p.x[0] and with_p.x[1] <= hull.x[1] + 1e-9
        assert hull.y[0] - 1e-9 <= with_p.y[0] and with_p.y[1] <= hull.y[1] + 1e-9
        a_p = (with_p.x[1] - with_p.x[0]) * (with_p.y[1] - with_p.y[0])
        a_h = (hull.x[1] - hull.x[0]) * (hull.y[1] - hull.y[0])
        tighter += a_p < 0.8 * a_h
    assert tighter >= 20


def test_a_sightings_pieces_are_taken_only_whole_and_inside_its_box():
    from localization.mrclam_cp_service import peer_box
    from msgs import Interval, PoseBox

    box = PoseBox(10**9, "r2", Interval(0.0, 2.0), Interval(0.0, 1.0), Interval(-1.0, 1.0))
    good = (0.0, 1.0, 0.0, 1.0, -1.0, 0.0, 1.0, 2.0, 0.0, 0.5, 0.0, 1.0)
    assert len(peer_box(box, good).pieces) == 2
    assert peer_box(box, good[:-1]).pieces == ()  # not whole
    assert peer_box(box, (0.0, 3.0, 0.0, 1.0, -1.0, 0.0)).pieces == ()  # outside the box
    assert peer_box(box).pieces == () and peer_box(box).x == (0.0, 2.0)


def test_a_sighting_box_is_aged_to_the_measurement_not_its_heading_to_the_use():
    """seen_by: the observer's heading is the one the bearing was measured from (the box
    stamped at the measurement); this robot's own motion since widens the position only.
    A box stamped before the measurement is aged to it first (aged_to)."""
    from localization.cp_rb_sightings import PeerBox, aged_to

    cfg = RangeBearingCPConfig()
    sg = Sightings(cfg, {})
    box = PeerBox(
        1.0, (0.0, 1.0), (2.0, 3.0), (0.5, 0.6), pieces=((0.0, 1.0, 2.0, 3.0, 0.5, 0.6),) * 2
    )
    o = sg.seen_by(1.2, 2, 2.0, 0.1, box)
    g = cfg.speed_cap_mps * 0.2
    assert np.allclose(o.other, (-g, 1 + g, 2 - g, 3 + g, 0.5 - 0.06, 0.6 + 0.06))
    assert np.allclose(o.pieces[0], o.other)
    old = aged_to(PeerBox(0.8, (0.0, 1.0), (2.0, 3.0), (0.5, 0.6)), 1.0, cfg)
    assert old.t == 1.0 and np.isclose(old.th[1], 0.6 + cfg.peer_yaw_rate_radps * 0.2)
    assert np.isclose(old.x[0], -cfg.peer_speed_mps * 0.2)
