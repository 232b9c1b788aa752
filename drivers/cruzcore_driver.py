"""CruzCore gyro driver: configure rate (and baud) with ``$MIA``, re-zero with ``$MIB,RESET``."""

from __future__ import annotations

from drivers.base import Clock, RawHook, wall_clock_ns
from drivers.cruzcore import CruzCoreCodec, config_command, reset_command
from drivers.stream import StreamDriver


class CruzCoreDriver(StreamDriver):
    """Streams :class:`msgs.GyroSample`; on connect sets the rate and zeroes the angle."""

    device = "gyro"

    def __init__(
        self,
        url: str,
        baud: int = 115200,
        rate_hz: int | None = 100,
        reset_on_open: bool = True,
        clock: Clock = wall_clock_ns,
        on_raw: RawHook | None = None,
        **kw: float,
    ) -> None:
        super().__init__(url, CruzCoreCodec(rate_hz), baud, clock, on_raw, **kw)
        self.rate_hz = rate_hz
        self.reset_on_open = reset_on_open

    def _on_open(self) -> None:
        assert self._t is not None
        if self.rate_hz is not None:
            self._t.write(config_command(rate_hz=self.rate_hz))
        if self.reset_on_open:
            self._t.write(reset_command())
            self.codec.reset_unwrap()

    def reset(self) -> bool:
        """Re-zero the gyro's angle (``$MIB,RESET``); the unwrapped angle restarts at 0."""
        ok = self.write(reset_command())
        self.codec.reset_unwrap()
        return ok

    def set_rate(self, rate_hz: int) -> bool:
        self.rate_hz = rate_hz
        self.codec.set_rate(rate_hz)
        return self.write(config_command(rate_hz=rate_hz))
