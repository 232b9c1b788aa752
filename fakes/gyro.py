"""Emulated CruzCore gyro: packets at the configured rate from the world's true yaw rate.

Measured rate = the gyro error model (bias, bias random walk, white noise, scale error;
fakes.world.gyro_model) applied to the robot's true yaw rate; the device integrates its
own angle from the measured rate (so it drifts like the real one) and wraps it at +-180
deg. ``$MIB,RESET`` zeroes the angle; ``$MIA`` changes the rate (1..100 Hz... up to the
runner's tick rate, several packets per tick above it) and the baud (recorded only: a pty
has no baud).
"""

from __future__ import annotations

from drivers.cruzcore import CommandParser, encode_packet
from fakes.streaming import PtyStreamEmulator
from fakes.world.gyro_model import GyroErrorModel


class GyroEmulator(PtyStreamEmulator):
    def __init__(
        self,
        robot: str = "r1",
        rate_hz: int = 100,
        error: GyroErrorModel | None = None,
        name: str = "gyro",
    ) -> None:
        super().__init__(name, robot)
        self.rate_hz = rate_hz
        self.baud = 115200
        self.error = error or GyroErrorModel()
        self.angle_rad = 0.0
        self.resets = 0
        self._parser = CommandParser()
        self._due = 0.0

    def on_input(self, data: bytes) -> None:
        for cmd in self._parser.feed(data):
            with self.lock:
                if cmd.kind == "reset":
                    self.angle_rad = 0.0
                    self.resets += 1
                else:
                    if cmd.rate_hz is not None and 1 <= cmd.rate_hz <= 1000:
                        self.rate_hz = cmd.rate_hz
                    if cmd.baud is not None:
                        self.baud = cmd.baud

    def tick(self, dt: float) -> None:
        if self._runner is None:
            return
        true_rate = self._runner.world.robots[self.robot_name].yaw_rate_radps
        out = []
        with self.lock:
            self._due += dt * self.rate_hz
            period = 1.0 / self.rate_hz
            while self._due >= 1.0:
                self._due -= 1.0
                rate = self.error.sample(true_rate, period)
                self.angle_rad += rate * period
                out.append(encode_packet(rate, self.angle_rad))
        if out:
            self.send(b"".join(out))
