"""What the emulated Pioneer reports: its standard SIP and the CONFIG packet's values.

``sip_packet`` packs the drive's odometry, wheel speeds, bumpers and flags into a
standard SIP in the robot's units (0x33 while the wheels are commanded to move, 0x32
at rest); ``config_values`` is the table a CONFIG command is answered with.
"""

from __future__ import annotations

import math

from drivers.arcos.packets import SIP_MOVING, SIP_STOPPED, encode_sip
from drivers.arcos.params import RobotParams
from fakes.pioneer_config import PioneerConfig
from fakes.pioneer_motion import DriveModel


def sip_packet(drive: DriveModel, params: RobotParams, battery_v: float) -> tuple[int, bytes]:
    """The ID and data of the standard SIP describing ``drive`` now."""
    p = params
    lv, rv = drive.wheel_speed
    moving = abs(lv) > 0.5 or abs(rv) > 0.5
    th_units = int(round(drive.odo[2] / p.angle_conv))
    th_units = ((th_units + 2048) % 4096) - 2048
    bumped = drive.bumped
    stall = (0x1 | 0x100) if bumped and moving else 0
    if bumped and drive.cur_trans > 0:
        stall |= 0x2 << 8  # a front bumper
    elif bumped and drive.cur_trans < 0:
        stall |= 0x2  # a rear bumper
    flags = (0x1 if drive.motors_enabled else 0) | (0x20 if drive.estopped else 0)
    rotvel = math.degrees((rv - lv) / 2.0 / drive.half_base_mm) * 10.0
    fields = {
        "XPOS": int(round(drive.odo[0] / p.dist_conv)) & 0x7FFF,
        "YPOS": int(round(drive.odo[1] / p.dist_conv)) & 0x7FFF,
        "THPOS": th_units,
        "L_VEL": int(round(lv / p.vel_conv)),
        "R_VEL": int(round(rv / p.vel_conv)),
        "BATTERY": int(round(battery_v * 10)) & 0xFF,
        "STALL_AND_BUMPERS": stall,
        "CONTROL": int(round(math.degrees(drive.head_target) / 360 * 4096))
        if drive.mode == "head"
        else 0,
        "FLAGS": flags,
        "COMPASS": 0,
        "GRIP_STATE": 0,
        "ANPORT": 0,
        "ANALOG": 0,
        "DIGIN": 0,
        "DIGOUT": 0,
        "BATTERYX10": int(round(battery_v * 10)),
        "CHARGESTATE": 0,
        "ROTVEL": int(round(rotvel)),
        "FAULTFLAGS": 0,
    }
    return (SIP_MOVING if moving else SIP_STOPPED), encode_sip(fields)


def config_values(c: PioneerConfig, drive: DriveModel) -> dict[str, int | str]:
    """The CONFIG packet's fields: the settings, with the limits the session set."""
    return {
        "Type": c.robot_class,
        "SubType": c.subclass,
        "SerialNumber": c.serial_number,
        "RotVelTop": c.rot_vel_max_degps,
        "TransVelTop": c.trans_vel_max_mmps,
        "RotAccelTop": 300,
        "TransAccelTop": 1000,
        "PwmMax": 1000,
        "Name": c.name,
        "SipCycleTime": c.sip_cycle_ms,
        "HostBaud": 0,
        "FrontSonar": 0,
        "LowBattery": 115,
        "RevCount": 16570,
        "Watchdog": c.watchdog_ms,
        "RotVelMax": int(drive.rot_max),
        "TransVelMax": int(drive.trans_max),
        "RotAccel": int(drive.rot_accel),
        "RotDecel": int(drive.rot_decel),
        "TransAccel": int(drive.trans_accel),
        "TransDecel": int(drive.trans_decel),
        "FrontBumps": 5,
        "RearBumps": 5,
        "ResetBaud": 0,
        "TicksMM": 128,
        "ShutdownVoltage": 105,
        "FirmwareVersion": c.firmware,
    }
