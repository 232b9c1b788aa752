"""Simulated world: floor plans, ground-truth robots, seeded noise."""

from fakes.world.diffdrive import DiffDriveRobot, SlipModel
from fakes.world.floorplan import BUILTIN, FloorPlan, load
from fakes.world.gps_model import GpsErrorModel
from fakes.world.gyro_model import GyroErrorModel
from fakes.world.ir_model import IrErrorModel
from fakes.world.landmarks import LandmarkSensorModel, pole_plan
from fakes.world.world import World

__all__ = [
    "BUILTIN",
    "DiffDriveRobot",
    "FloorPlan",
    "GpsErrorModel",
    "GyroErrorModel",
    "IrErrorModel",
    "LandmarkSensorModel",
    "SlipModel",
    "World",
    "load",
    "pole_plan",
]
