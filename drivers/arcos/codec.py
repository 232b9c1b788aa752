"""ARCOS byte stream -> messages: SIP to RobotOdometry, CONFIG to RobotInfo.

Odometry follows ARIA: positions are 15 bits (``raw & 0x7FFF``); the difference with
the previous SIP is unwrapped (subtract 0x8000 if > 0x1000, add it if < -0x1000) and
accumulated in the robot's own frame, and the heading difference is wrapped to
(-pi, pi]. The first SIP only sets the reference (pose 0 there); :meth:`reset_reference`
does it again (after SETO or a reconnect). Non-SIP packets other than CONFIG and
ENCODER are passed through as :class:`ArcosPacket` for the driver (sync replies, reset).

ARCOS has no sequence numbers, so a packet lost on the line leaves no trace in the stream
and ``stats.frames_lost`` stays 0; corruption shows in ``bad_checksums``, ``resyncs`` and
``bytes_skipped``, and a packet whose checksum holds but whose content does not fit its ID
(a SIP too short) in ``malformed``.
"""

from __future__ import annotations

import math

from drivers.arcos.packet import ArcosPacket, PacketParser
from drivers.arcos.packets import (
    CONFIG_ID,
    ENCODER_ID,
    SIP_MOVING,
    SIP_STOPPED,
    PacketError,
    decode_config,
    decode_encoder,
    decode_sip,
)
from drivers.arcos.params import P3DX_SH, RobotParams
from msgs import Pose2D, RobotInfo, RobotOdometry, wrap_angle

POS_MASK = 0x7FFF
POS_WRAP = 0x8000
POS_JUMP = 0x1000


def unwrap15(prev: int, new: int) -> int:
    """Signed change between two 15-bit positions (ARIA's rule)."""
    d = (new & POS_MASK) - (prev & POS_MASK)
    if d > POS_JUMP:
        d -= POS_WRAP
    elif d < -POS_JUMP:
        d += POS_WRAP
    return d


class OdometryTracker:
    """Integrates SIP positions into an unwrapped pose in metres/radians."""

    def __init__(self, params: RobotParams = P3DX_SH) -> None:
        self.params = params
        self._last: tuple[int, int, int] | None = None
        self.pose = Pose2D()

    def reset_reference(self, pose: Pose2D | None = None) -> None:
        self._last = None
        self.pose = pose or Pose2D()

    def update(self, xpos: int, ypos: int, thpos: int) -> Pose2D:
        if self._last is None:
            self._last = (xpos, ypos, thpos)
            return self.pose
        lx, ly, lth = self._last
        k = self.params.dist_conv / 1000.0
        dx = unwrap15(lx, xpos) * k
        dy = unwrap15(ly, ypos) * k
        dth = wrap_angle((thpos - lth) * self.params.angle_conv)
        self._last = (xpos, ypos, thpos)
        self.pose = Pose2D(self.pose.x + dx, self.pose.y + dy, wrap_angle(self.pose.theta + dth))
        return self.pose


class ArcosCodec:
    """Pure ARCOS decoder following the drivers.base Codec contract."""

    def __init__(self, params: RobotParams = P3DX_SH, inter_byte_timeout_ns: int = 100_000_000):
        self.parser = PacketParser(inter_byte_timeout_ns)
        self.stats = self.parser.stats
        self.odometry = OdometryTracker(params)
        self._encoders: tuple[int, int] | None = None

    @property
    def params(self) -> RobotParams:
        return self.odometry.params

    @params.setter
    def params(self, value: RobotParams) -> None:
        self.odometry.params = value

    def feed(self, data: bytes, stamp_ns: int) -> list[RobotOdometry | RobotInfo | ArcosPacket]:
        out: list[RobotOdometry | RobotInfo | ArcosPacket] = []
        for pkt in self.parser.feed(data, stamp_ns):
            try:
                if pkt.packet_id in (SIP_STOPPED, SIP_MOVING):
                    out.append(self.odometry_message(pkt))
                elif pkt.packet_id == CONFIG_ID:
                    cfg = decode_config(pkt.data)
                    out.append(
                        RobotInfo(
                            pkt.stamp_ns,
                            str(cfg.get("Name", "")),
                            str(cfg.get("Type", "")),
                            str(cfg.get("SubType", "")),
                            cfg,
                        )
                    )
                elif pkt.packet_id == ENCODER_ID:
                    self._encoders = decode_encoder(pkt.data)
                else:
                    out.append(pkt)
            except PacketError:
                self.stats.malformed += 1
        return out

    def odometry_message(self, pkt: ArcosPacket) -> RobotOdometry:
        raw = decode_sip(pkt.data)
        p = self.params
        pose = self.odometry.update(raw["XPOS"], raw["YPOS"], raw["THPOS"])
        lv = raw["L_VEL"] * p.vel_conv / 1000.0
        rv = raw["R_VEL"] * p.vel_conv / 1000.0
        if "ROTVEL" in raw:
            w = math.radians(raw["ROTVEL"] / 10.0)
        else:
            w = (raw["R_VEL"] - raw["L_VEL"]) * p.vel_conv / 2.0 * p.diff_conv
        battery = raw["BATTERYX10"] / 10.0 if raw.get("BATTERYX10") else raw["BATTERY"] / 10.0
        sb = raw["STALL_AND_BUMPERS"]
        flags = raw["FLAGS"]
        enc = self._encoders
        return RobotOdometry(
            stamp_ns=pkt.stamp_ns,
            pose=pose,
            left_vel_mps=lv,
            right_vel_mps=rv,
            linear_vel_mps=0.5 * (lv + rv),
            angular_vel_radps=w,
            battery_v=battery,
            # AMRISim sends every SIP as type 0x32 ("stopped"): the velocities say it too
            moving=pkt.packet_id == SIP_MOVING
            or any(raw.get(k, 0) != 0 for k in ("L_VEL", "R_VEL", "ROTVEL")),
            motors_enabled=bool(flags & 0x1),
            estop=bool(flags & 0x20),
            left_stall=bool(sb & 0x1),
            right_stall=bool(sb & 0x100),
            front_bumpers=(sb >> 9) & 0x7F,
            rear_bumpers=(sb >> 1) & 0x7F,
            left_encoder=enc[0] if enc else None,
            right_encoder=enc[1] if enc else None,
            raw=raw,
        )
