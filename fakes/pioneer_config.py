"""The emulated Pioneer's firmware settings: identity, SIP cycle, watchdog, motion limits.

``PioneerConfig`` is what the ARCOS controller's FLASH holds and reports: the names
answered to SYNC2 and CONFIG, the SIP cycle and watchdog times, the default
acceleration limits and top speeds, the battery voltage, an optional baud rate at
which the port paces its output.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass
class PioneerConfig:
    """Firmware settings of one emulated controller (times in ms, speeds in mm/s, deg/s)."""

    name: str = "hilnav-fake"
    robot_class: str = "Pioneer"
    subclass: str = "p3dx-sh"
    sip_cycle_ms: int = 100
    watchdog_ms: int = 2000
    trans_accel_mmps2: int = 300
    trans_decel_mmps2: int = 300
    rot_accel_degps2: int = 100
    rot_decel_degps2: int = 100
    trans_vel_max_mmps: int = 1500
    rot_vel_max_degps: int = 360
    battery_v: float = 12.8
    baud: int | None = None
    serial_number: str = "FAKE0001"
    firmware: str = "hilnav-arcos-emu 1.0"
