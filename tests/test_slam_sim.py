"""EKF-SLAM on the simulated Pioneer with ground truth: the fake landmark sensor, and the
consistency check (NEES of the vehicle pose inside its chi-square band), seeded."""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.stats

from fakes.world import LandmarkSensorModel, SlipModel, World, pole_plan
from mapping.slam.models import wrap
from mapping.slam.service import LandmarkSlam, SlamConfig
from msgs import Pose2D, RobotOdometry

WHEELBASE = 0.33
SLIP = 0.004  # per wheel, 1-sigma relative white slip per sqrt(m) (SlipModel)


def run(seed: int, seconds: float = 40.0, clutter: float = 0.0, association: str = "nn"):
    """Drive a circle of 6 m radius among jittered poles; return (errors (T, 3), NEES (T,),
    the service, the world). White-noise slip only: the EKF models white noise."""
    world = World(pole_plan(seed=seed), seed=seed)
    start = Pose2D(0.0, -6.0, 0.0)
    robot = world.add_robot(
        "r1",
        pose=start,
        wheelbase_m=WHEELBASE,
        slip=SlipModel(radius_error=0.0, slip_per_sqrt_m=SLIP, wheelbase_error_m=0.0),
    )
    v, rad = 0.5, 6.0
    robot.command_wheels(v * (1 - WHEELBASE / (2 * rad)), v * (1 + WHEELBASE / (2 * rad)))
    sensor = LandmarkSensorModel(
        max_range_m=10.0,
        fov_rad=math.radians(180),
        sigma_range_m=0.05,
        sigma_bearing_rad=math.radians(1.0),
        p_detect=0.85,
        clutter_per_scan=clutter,
        seed=seed + 100,
    )
    cfg = SlamConfig(
        vehicle="unicycle",
        sigma_d_per_sqrt_m=SLIP / math.sqrt(2),
        sigma_theta_per_sqrt_m=SLIP * math.sqrt(2) / WHEELBASE,
        sigma_theta_per_sqrt_rad=0.0,
        sigma_range_m=0.05,
        sigma_bearing_rad=math.radians(1.0),
        max_range_m=10.0,
        association=association,
        initial_pose=(start.x, start.y, start.theta),
        initial_sigma=(1e-4, 1e-4, 1e-5),
    )
    slam = LandmarkSlam(cfg)
    dt = 0.1
    enc0 = np.array(robot.encoder_m())
    errs, nees = [], []
    for step in range(int(seconds / dt)):
        world.step(dt)
        enc = np.array(robot.encoder_m())
        dl, dr = enc - enc0
        enc0 = enc
        slam.predict_increment(0.5 * (dl + dr), (dr - dl) / WHEELBASE)
        if step % 2 == 1:  # 5 Hz scans
            slam.on_scan(sensor.scan(world, "r1"))
            truth = robot.pose
            e = slam.ekf.vehicle - np.array([truth.x, truth.y, truth.theta])
            e[2] = wrap(e[2])
            errs.append(e)
            nees.append(float(e @ np.linalg.solve(slam.ekf.vehicle_cov, e)))
    return np.array(errs), np.array(nees), slam, world


def test_sensor_sees_poles_with_noise_fov_and_misses():
    world = World(pole_plan(seed=1), seed=1)
    world.add_robot("r1", pose=Pose2D(0.0, 0.0, 0.5))
    sensor = LandmarkSensorModel(max_range_m=12.0, fov_rad=math.radians(120), p_detect=0.8, seed=3)
    pose = world.robots["r1"].pose
    lm = world.plan.landmarks
    d = lm - [pose.x, pose.y]
    visible = (np.hypot(*d.T) <= 12.0) & (
        np.abs(wrap(np.arctan2(d[:, 1], d[:, 0]) - pose.theta)) <= math.radians(60)
    )
    seen = []
    for _ in range(200):
        scan = sensor.scan(world, "r1")
        truth = sensor.last_truth
        assert len(truth) == len(scan.ranges_m) == len(scan.bearings_rad)
        assert set(truth) <= set(np.nonzero(visible)[0])
        for i, r, b in zip(truth, scan.ranges_m, scan.bearings_rad, strict=True):
            assert r == pytest.approx(np.hypot(*d[i]), abs=0.3)
            assert abs(wrap(b - (np.arctan2(d[i, 1], d[i, 0]) - pose.theta))) < 0.1
        seen.append(len(truth))
    rate = np.mean(seen) / visible.sum()
    assert 0.7 < rate < 0.9  # missed detections at 1 - p_detect
    # same seed, same scans
    a = LandmarkSensorModel(seed=9, clutter_per_scan=2.0).scan(world, "r1")
    b = LandmarkSensorModel(seed=9, clutter_per_scan=2.0).scan(world, "r1")
    assert a == b
    with pytest.raises(ValueError, match="bearing_zero"):
        LandmarkSensorModel(bearing_zero="z")


def test_sensor_paper_convention():
    world = World(pole_plan(seed=1), seed=1)
    world.add_robot("r1", pose=Pose2D(0.0, 0.0, 0.0))
    sx = LandmarkSensorModel(seed=4, sigma_bearing_rad=0.0, sigma_range_m=0.0, p_detect=1.0)
    sy = LandmarkSensorModel(
        seed=4, sigma_bearing_rad=0.0, sigma_range_m=0.0, p_detect=1.0, bearing_zero="y"
    )
    a, b = sx.scan(world, "r1"), sy.scan(world, "r1")
    np.testing.assert_allclose(np.array(b.bearings_rad) - np.array(a.bearings_rad), math.pi / 2)


def test_nees_of_vehicle_pose_is_inside_its_band():
    """Monte Carlo over 8 seeded runs: the average NEES (3 dof) over runs at each scan must
    lie in the 95% band of chi2(3N)/N for most scans and on average."""
    runs = 8
    nees = np.array([run(seed)[1] for seed in range(runs)])  # (runs, T)
    anees = nees.mean(axis=0)
    lo = scipy.stats.chi2.ppf(0.025, 3 * runs) / runs
    hi = scipy.stats.chi2.ppf(0.975, 3 * runs) / runs
    inside = (anees >= lo) & (anees <= hi)
    assert inside.mean() > 0.85, (inside.mean(), anees.mean())
    assert lo < anees.mean() < hi


def test_slam_on_simulated_pioneer_maps_the_poles():
    errs, _, slam, world = run(seed=11, seconds=60.0, clutter=0.5)
    assert np.abs(errs[:, :2]).max() < 0.5  # the pose stays within decimetres
    lm = slam.ekf.landmarks
    truth = world.plan.landmarks
    nearest = np.min(np.hypot(*(lm[:, None, :] - truth[None]).transpose(2, 0, 1)), axis=1)
    assert len(lm) >= 10
    assert np.all(nearest < 0.5)  # no clutter landmark confirmed, each pole found once
    assert len(
        set(np.argmin(np.hypot(*(lm[:, None, :] - truth[None]).transpose(2, 0, 1)), 1))
    ) == len(lm)


def test_odometry_messages_drive_the_unicycle_model():
    slam = LandmarkSlam(SlamConfig(vehicle="unicycle"))
    for k in range(11):
        th = 0.1 * k
        pose = Pose2D(math.sin(th), 1 - math.cos(th), th)  # unit circle
        est = slam.on_odometry(RobotOdometry(k * 10**8, pose, 0, 0, 0, 0, 12.0, True, True))
    assert est.pose.theta == pytest.approx(1.0)
    assert est.pose.x == pytest.approx(math.sin(1.0), abs=1e-3)
    assert est.pose.y == pytest.approx(1 - math.cos(1.0), abs=1e-3)
    assert est.covariance[0] > 0 and est.source == "ekf_slam"
    with pytest.raises(ValueError, match="ackermann"):
        from msgs import VehicleControl

        slam.on_control(VehicleControl(0, 1.0, 0.0))
