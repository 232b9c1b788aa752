"""The emulated devices of one robot, from its config: the one path from a
:class:`~hilnav.config.RobotConfig` to the fakes (``hilnav fake``, the daemon's "sim"
ports, the demo, tests).

:func:`build_fakes` takes the robot's config (name, wheel base, IR board and mounts, rates,
GPS datum, [simulation] plan/seed/GPS rate/corruption) and the :class:`FakeKnobs` that
are not part of a config (faults, link directory, replayed logs), and makes one emulator
per device through the device table (:mod:`hilnav.devices`). :func:`override` applies
``hilnav fake``'s command-line options to a config, checked like the config file itself.
:class:`FakeProcess` runs ``hilnav fake`` as a child of the daemon, handing it the
resolved config.
"""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import threading
from collections.abc import Iterable
from typing import Any

from drivers.clock import now_ns
from fakes.runner import FakeRunner
from fakes.world import World
from hilnav.config import ConfigError, RobotConfig, config_data, parse_config
from hilnav.devices import DEVICES, FakeKnobs
from hilnav.errors import CliError
from msgs import GroundTruth

# hilnav fake's options -> the config keys they set
OPTION_KEYS = {
    "robot": ("name",),
    "plan": ("simulation", "plan"),
    "seed": ("simulation", "seed"),
    "gps_rate": ("simulation", "gps_rate_hz"),
    "corrupt": ("simulation", "corrupt"),
    "ir_rate": ("devices", "ir", "rate_hz"),
    "gyro_rate": ("devices", "gyro", "rate_hz"),
}


def override(cfg: RobotConfig, **options: Any) -> RobotConfig:
    """``cfg`` with the given ``hilnav fake`` options (None = not given) set, checked as
    a config file is (a bad value names its option and config key)."""
    data = config_data(cfg)
    given = {k: v for k, v in options.items() if v is not None}
    for opt, value in given.items():
        path = OPTION_KEYS.get(opt)
        if path is None:
            raise ValueError(f"unknown fake option {opt!r}")
        node = data
        for part in path[:-1]:
            node = node[part]
        node[path[-1]] = value
    if not given:
        return cfg
    try:
        return parse_config(data, cfg.source)
    except ConfigError as exc:
        flags = ", ".join("--" + k.replace("_", "-") for k in given)
        raise CliError(f"{flags}: {exc}") from None


def build_fakes(
    cfg: RobotConfig, knobs: FakeKnobs | None = None, devices: Iterable[str] | None = None
) -> FakeRunner:
    """A runner with the world and one emulator per device (not started).

    ``devices``: which to emulate (default: those the config enables)."""
    knobs = knobs or FakeKnobs()
    names = [d.name for d in DEVICES.values() if d.section(cfg).enabled]
    if devices is not None:
        names = list(devices)
        bad = sorted(set(names) - set(DEVICES))
        if bad:
            raise CliError(f"--devices: unknown device {bad[0]!r}; choose from {','.join(DEVICES)}")
    if not 0.0 <= knobs.drop <= 1.0:
        raise CliError(f"--drop {knobs.drop}: a fraction between 0 and 1")
    unknown = set(knobs.replay) - {"gps"}
    if unknown:
        raise CliError(f"--replay {sorted(unknown)[0]}=...: only gps can be replayed from a log")
    world = World.from_name(cfg.simulation.plan, seed=cfg.simulation.seed)
    world.add_robot(cfg.name, wheelbase_m=cfg.geometry.wheel_base_m)
    runner = FakeRunner(world, link_dir=knobs.link_dir)
    for name in names:
        try:
            runner.add(DEVICES[name].emulator(cfg, knobs))
        except ValueError as exc:
            raise CliError(f"{name}: {exc}") from None
    return runner


def sim_devices(cfg: RobotConfig) -> list[str]:
    """The enabled devices whose port is "sim" (what the daemon asks the fake for)."""
    return [
        d.name for d in DEVICES.values() if d.section(cfg).enabled and d.section(cfg).port == "sim"
    ]


class TruthPublisher:
    """A pseudo-emulator: publishes the world's true pose of one robot on the Zenoh bus
    (``hilnav/<robot>/truth``, msgs.GroundTruth, wall-clock stamps like the drivers') at
    ``rate_hz``, so the daemon logs the truth beside what its sensors say."""

    name = "truth"

    def __init__(self, robot: str, bus, rate_hz: float = 10.0) -> None:
        self.robot = robot
        self.bus = bus
        self.rate_hz = rate_hz
        self.published = 0
        self._runner = None
        self._due = 0.0

    def start(self, runner) -> None:
        self._runner = runner

    def tick(self, dt: float) -> None:
        if self._runner is None:
            return
        self._due += dt * self.rate_hz
        if self._due < 1.0:
            return
        self._due -= int(self._due)
        r = self._runner.world.robots[self.robot]
        msg = GroundTruth(now_ns(), self.robot, r.pose, r.speed_mps, r.yaw_rate_radps)
        try:
            self.bus.publish("truth", msg)
            self.published += 1
        except Exception:
            pass

    def stop(self) -> None:
        self._runner = None

    def ports(self) -> dict[str, str]:
        return {}


class FakeProcessError(RuntimeError):
    """The emulated devices did not start: the message carries their stderr."""


class FakeProcess:
    """``hilnav fake`` in a subprocess for the devices of ``cfg`` whose port is "sim".

    The resolved config goes to the child as one JSON line on its stdin, which the child
    then watches: when this process dies for any reason (SIGKILL included) the pipe closes
    and the child stops, so no orphan keeps publishing a world nobody drives."""

    def __init__(
        self, cfg: RobotConfig, zenoh_endpoint: str | None, timeout_s: float = 30.0
    ) -> None:
        cmd = [sys.executable, "-m", "hilnav", "fake", "--config", "-"]
        cmd += ["--devices", ",".join(sim_devices(cfg))]
        if zenoh_endpoint:
            cmd += ["--zenoh-connect", zenoh_endpoint]
        self.proc = subprocess.Popen(
            cmd,
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        assert self.proc.stdin is not None
        self.proc.stdin.write(json.dumps(config_data(cfg)) + "\n")
        self.proc.stdin.flush()
        self.ports = self._read_ports(timeout_s)

    def _read_ports(self, timeout_s: float) -> dict[str, str]:
        got: list[str] = []
        assert self.proc.stdout is not None
        out = self.proc.stdout
        t = threading.Thread(target=lambda: got.append(out.readline()), daemon=True)
        t.start()
        t.join(timeout_s)
        try:
            ports = json.loads(got[0] if got else "")
        except ValueError:
            self.stop()
            err = self.proc.stderr.read() if self.proc.stderr else ""
            raise FakeProcessError(
                f"the emulated devices did not start: {err.strip()[-400:]}"
            ) from None
        return {str(k): str(v) for k, v in ports.items()}

    def stop(self) -> None:
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(timeout=5.0)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(timeout=5.0)
        for s in (self.proc.stdin, self.proc.stdout, self.proc.stderr):
            if s is not None:
                s.close()
