"""Simulated world: floor plans, ground-truth robots, seeded noise."""

from fakes.world.diffdrive import DiffDriveRobot, SlipModel
from fakes.world.floorplan import BUILTIN, FloorPlan, load
from fakes.world.world import World

__all__ = ["BUILTIN", "DiffDriveRobot", "FloorPlan", "SlipModel", "World", "load"]
