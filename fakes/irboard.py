"""Emulated IR ADC board: ray casts the world, applies the Sharp curve and the ADC.

Each sample: true distances from World.ranges with the sensors' mounting poses; the IR
error model (fakes.world.ir_model) turns them into raw counts (forward voltage curve with
the near-range ambiguity, voltage noise, dropouts, quantisation). The board sends one
frame per sample at its rate and obeys SET_RATE, on one of three links:

- ``serial``: hilnav's serial framing on a pty;
- ``slcan``: CAN frames behind an emulated slcan USB-CAN adapter on a pty
  (fakes.slcan), so the driver opens it with python-can's ``slcan`` interface from
  another process;
- ``python-can``: CAN frames on a python-can bus (``virtual`` in-process, or
  ``socketcan`` where the kernel has vcan).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from drivers.irboard.canframe import pack_sample, unpack_command
from drivers.irboard.convert import IrBoardConfig
from drivers.irboard.serialframe import RawSample, SerialFrameDecoder, encode_sample
from drivers.sharp import MAX_VALID_M
from fakes.slcan import SlcanAdapter
from fakes.streaming import PtyStreamEmulator
from fakes.world.ir_model import IrErrorModel

MAX_CAST_M = 2.0 * MAX_VALID_M  # beyond this nothing is reflected (curve near baseline)


class IrBoardEmulator(PtyStreamEmulator):
    def __init__(
        self,
        robot: str = "r1",
        config: IrBoardConfig | None = None,
        error: IrErrorModel | None = None,
        link: str = "serial",
        can_interface: str = "virtual",
        can_channel: str = "hilnav",
        seed: int = 0,
        name: str = "ir",
    ) -> None:
        super().__init__(name, robot)
        if link not in ("serial", "slcan", "python-can"):
            raise ValueError(f"ir.link must be serial, slcan or python-can, not {link!r}")
        self.config = config or IrBoardConfig()
        self.error = error or IrErrorModel(adc_bits=self.config.adc_bits, vref_v=self.config.vref_v)
        self.link = link
        self.can_interface = can_interface
        self.can_channel = can_channel
        self.rate_hz = self.config.rate_hz
        self.rng = np.random.default_rng(seed)
        self.seq = 0
        self.samples = 0
        self.adapter: SlcanAdapter | None = None
        self.bus: Any = None
        self._decoder = SerialFrameDecoder(commands=True)
        self._due = 0.0
        self._mounts = self.config.mounts_array()

    # -- lifecycle ------------------------------------------------------------------------
    def start(self, runner) -> None:
        if self.link == "serial":
            super().start(runner)
            return
        self._runner = runner
        if self.link == "slcan":
            self.adapter = SlcanAdapter(runner.link_dir / f"{self.name}-slcan")
            self.adapter.nodes.append(self._on_frame)
            self.adapter.start()
        else:
            import can

            self.bus = can.Bus(interface=self.can_interface, channel=self.can_channel)
            self._notifier = can.Notifier(
                self.bus, [lambda m: self._on_frame(m.arbitration_id, bytes(m.data), False)]
            )

    def stop(self) -> None:
        if self.adapter is not None:
            self.adapter.stop()
        if self.bus is not None:
            self._notifier.stop()
            self.bus.shutdown()
            self.bus = None
        super().stop()

    def ports(self) -> dict[str, str]:
        if self.link == "slcan" and self.adapter is not None:
            return {f"{self.name}_can": f"slcan:{self.adapter.path}"}
        if self.link == "python-can":
            return {f"{self.name}_can": f"{self.can_interface}:{self.can_channel}"}
        return super().ports()

    # -- commands -------------------------------------------------------------------------
    def on_input(self, data: bytes) -> None:
        for cmd in self._decoder.feed(data):
            if cmd.board_id == self.config.board_id and cmd.rate_hz:
                self._set_rate(cmd.rate_hz)

    def _on_frame(self, arb_id: int, data: bytes, extended: bool) -> None:
        cmd = None if extended else unpack_command(arb_id, data)
        if cmd is not None and cmd[0] == self.config.board_id:
            self._set_rate(cmd[1])

    def _set_rate(self, rate_hz: int) -> None:
        if 1 <= rate_hz <= 1000:
            with self.lock:
                self.rate_hz = rate_hz

    # -- sampling -------------------------------------------------------------------------
    def sample_counts(self) -> tuple[int, ...]:
        """Raw counts for the robot's current true pose (world locked by the caller)."""
        assert self._runner is not None
        true = self._runner.world.ranges(self.robot_name, self._mounts, MAX_CAST_M)
        true = np.where(np.asarray(true) >= MAX_CAST_M, np.inf, true)
        return tuple(int(c) for c in self.error.counts(true, self.rng))

    def tick(self, dt: float) -> None:
        if self._runner is None:
            return
        with self.lock:
            self._due += dt * self.rate_hz
            n = int(self._due)
            self._due -= n
        for _ in range(n):
            s = RawSample(
                self.config.board_id, self.seq, self.config.adc_bits, self.sample_counts()
            )
            self.seq = (self.seq + 1) & 0xFFFF
            self.samples += 1
            if self.link == "serial":
                self.send(encode_sample(s))
            else:
                arb, data = pack_sample(s)
                if self.adapter is not None:
                    self.adapter.deliver(arb, data)
                elif self.bus is not None:
                    import can

                    try:
                        self.bus.send(
                            can.Message(arbitration_id=arb, data=data, is_extended_id=False)
                        )
                    except can.CanError:
                        pass
