"""``hilnav demo``: the emulated Pioneer on a pty, driven around a square by the driver.

Prints the odometry against the world's ground truth at every corner. (The robot daemon
issue grows this into the full demo with all sensors, services, Zenoh and MCAP.)
"""

from __future__ import annotations

import argparse
import json
import math
import time

from drivers.arcos.driver import ArcosDriver
from fakes.pioneer import PioneerEmulator
from fakes.runner import FakeRunner
from fakes.world import World
from msgs import Pose2D, RobotOdometry


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("demo", help="run the demo: a simulated Pioneer driven by the driver")
    p.add_argument("--side", type=float, default=1.0, help="side of the square in metres")
    p.add_argument("--seed", type=int, default=0)
    p.set_defaults(func=run)


def _drive_until(driver: ArcosDriver, v: float, w: float, done) -> RobotOdometry | None:  # noqa: ANN001
    last = None
    deadline = time.monotonic() + 30.0
    while time.monotonic() < deadline:
        driver.set_velocity(v, w)
        for m in driver.read(0.1):
            if isinstance(m, RobotOdometry):
                last = m
        if last is not None and done(last):
            return last
    return last


def run(args: argparse.Namespace) -> int:
    world = World.from_name("open_field", seed=args.seed)
    world.add_robot("r1", Pose2D(0.0, 0.0, 0.0))
    runner = FakeRunner(world)
    runner.add(PioneerEmulator("r1", seed=args.seed))
    with runner:
        driver = ArcosDriver(runner.ports()["arcos"])
        info = driver.open()
        print(f"connected to {info.name} ({info.robot_class} {info.subclass}) on {driver.url}")
        for corner in range(4):
            start = _drive_until(driver, 0.0, 0.0, lambda m: True)
            sx, sy = start.pose.x, start.pose.y
            _drive_until(
                driver,
                0.3,
                0.0,
                lambda m, sx=sx, sy=sy: (
                    math.hypot(m.pose.x - sx, m.pose.y - sy) >= args.side - 0.02
                ),
            )
            goal = math.remainder((corner + 1) * math.pi / 2, 2 * math.pi)
            odo = _drive_until(
                driver,
                0.0,
                0.4,
                lambda m, g=goal: abs(math.remainder(g - m.pose.theta, 2 * math.pi)) < 0.03,
            )
            truth = world.robots["r1"].pose
            print(
                json.dumps(
                    {
                        "corner": corner + 1,
                        "odometry": [
                            round(odo.pose.x, 3),
                            round(odo.pose.y, 3),
                            round(odo.pose.theta, 3),
                        ],
                        "truth": [round(truth.x, 3), round(truth.y, 3), round(truth.theta, 3)],
                    }
                )
            )
        driver.stop()
        driver.close()
    print("done: the odometry drifts from the truth by wheel slip, as on the real robot")
    return 0
