"""The simulated world: a floor plan, robots in it, a clock, seeded randomness.

The world is stepped by whoever owns it (the fake-device process) at a fixed period;
device emulators read the truth from it (ranges by ray casting, yaw rate, positions).
It is deterministic for a given seed and sequence of commands.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from fakes.world.diffdrive import DiffDriveRobot, SlipModel
from fakes.world.floorplan import FloorPlan, load
from msgs import Pose2D


@dataclass
class World:
    """Ground truth for one or more robots in one floor plan."""

    plan: FloorPlan
    seed: int = 0
    time_ns: int = 0
    robots: dict[str, DiffDriveRobot] = field(default_factory=dict)
    robot_radius_m: float = 0.25

    def __post_init__(self) -> None:
        self.rng = np.random.default_rng(self.seed)

    @classmethod
    def from_name(cls, plan: str, seed: int = 0) -> World:
        return cls(load(plan), seed=seed)

    def add_robot(
        self,
        name: str,
        pose: Pose2D | None = None,
        wheelbase_m: float = 0.33,
        slip: SlipModel | None = None,
    ) -> DiffDriveRobot:
        """Place a robot (at the plan's start pose unless given); its noise is seeded."""
        if name in self.robots:
            raise ValueError(f"robot {name!r} already in the world")
        start = pose or Pose2D(*self.plan.start)
        robot = DiffDriveRobot(
            name,
            pose=start,
            wheelbase_m=wheelbase_m,
            slip=slip or SlipModel(),
            seed=int(self.rng.integers(2**31)),
        )
        self.robots[name] = robot
        return robot

    def step(self, dt: float) -> None:
        """Advance every robot by ``dt`` seconds; a robot that would enter a wall stalls."""
        for robot in self.robots.values():
            before = robot.pose
            robot.step(dt)
            clear_before = self.plan.clearance(before.x, before.y)
            clear_after = self.plan.clearance(robot.pose.x, robot.pose.y)
            if clear_after < self.robot_radius_m and clear_after < clear_before:
                robot.pose = before  # bumped into a wall: the wheels spin, the body stays
                robot.bumped = True
            else:
                robot.bumped = False
        self.time_ns += int(round(dt * 1e9))

    def ranges(self, robot: str, mounts: np.ndarray, max_range: float) -> np.ndarray:
        """True distances from sensors mounted at (K, 3) (x, y, yaw in the robot frame)."""
        r = self.robots[robot]
        c, s = np.cos(r.pose.theta), np.sin(r.pose.theta)
        mounts = np.atleast_2d(mounts)
        ox = r.pose.x + c * mounts[:, 0] - s * mounts[:, 1]
        oy = r.pose.y + s * mounts[:, 0] + c * mounts[:, 1]
        return self.plan.cast(np.stack([ox, oy], 1), r.pose.theta + mounts[:, 2], max_range)
