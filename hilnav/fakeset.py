"""Assemble the emulated devices of one robot (used by ``hilnav fake``, the demo, tests)."""

from __future__ import annotations

from dataclasses import dataclass, field

from fakes.pioneer import PioneerEmulator, PioneerFaults
from fakes.runner import FakeRunner
from fakes.world import World
from fakes.world.floorplan import BUILTIN
from hilnav.errors import CliError


@dataclass
class FakeOptions:
    seed: int = 0
    plan: str = "office"
    robot: str = "r1"
    link_dir: str | None = None
    baud: int | None = None
    corrupt: float = 0.0
    drop: float = 0.0
    vanish_after: float | None = None
    vanish_for: float = 2.0
    replay: dict[str, str] = field(default_factory=dict)
    config: str | None = None
    devices: tuple[str, ...] = ("arcos", "ir", "gyro", "gps")
    ir_link: str = "serial"  # serial | slcan | python-can (virtual bus, in-process only)
    ir_rate_hz: int = 20
    gyro_rate_hz: int = 100
    gps_rate_hz: float = 1.0
    replay_fast: bool = False
    ir_board: dict = field(default_factory=dict)  # IrBoardConfig fields (from --config)
    wheelbase_m: float = 0.33


def apply_config(opts: FakeOptions) -> FakeOptions:
    """Options from the robot TOML in ``opts.config`` (if any): its name, [simulation] plan,
    seed, GPS rate and corruption, which devices are enabled, the IR board (link, rate, id,
    ADC, mounts) and the gyro rate. Options left at their defaults take the file's values;
    options given on the command line win."""
    if not opts.config:
        return opts
    from dataclasses import fields, replace

    from hilnav.config import ConfigError, load_config

    try:
        cfg = load_config(opts.config)
    except (ConfigError, OSError) as exc:
        raise CliError(f"--config {opts.config}: {exc}") from None
    d, sim = cfg.devices, cfg.simulation
    from_file = {
        "robot": cfg.name,
        "plan": sim.plan,
        "seed": sim.seed,
        "gps_rate_hz": sim.gps_rate_hz,
        "corrupt": sim.corrupt,
        "devices": tuple(n for n in ("arcos", "ir", "gyro", "gps") if getattr(d, n).enabled),
        "ir_link": "slcan" if d.ir.link == "can" else "serial",
        "ir_rate_hz": d.ir.rate_hz,
        "gyro_rate_hz": d.gyro.rate_hz,
    }
    defaults = FakeOptions()
    changes = {
        f.name: from_file[f.name]
        for f in fields(FakeOptions)
        if f.name in from_file and getattr(opts, f.name) == getattr(defaults, f.name)
    }
    changes["ir_board"] = {
        "board_id": d.ir.board_id,
        "adc_bits": d.ir.adc_bits,
        "vref_v": d.ir.vref_v,
        "mounts": tuple(tuple(m) for m in cfg.geometry.ir_mounts_rad()),
    }
    changes["wheelbase_m"] = cfg.geometry.wheel_base_m
    return replace(opts, **changes)


def build_fakes(opts: FakeOptions) -> FakeRunner:
    """A runner with the world and the requested emulators (not started)."""
    opts = apply_config(opts)
    if opts.plan not in BUILTIN:
        raise CliError(
            f"--plan {opts.plan!r}: unknown floor plan; choose one of {', '.join(BUILTIN)}"
        )
    for name, value in (("--corrupt", opts.corrupt), ("--drop", opts.drop)):
        if not 0.0 <= value <= 1.0:
            raise CliError(f"{name} {value}: a fraction between 0 and 1")
    unknown = set(opts.replay) - {"gps"}
    if unknown:
        raise CliError(f"--replay {sorted(unknown)[0]}=...: only gps can be replayed from a log")
    bad = set(opts.devices) - {"arcos", "ir", "gyro", "gps"}
    if bad:
        raise CliError(
            f"--devices: unknown device {sorted(bad)[0]!r}; choose from arcos,ir,gyro,gps"
        )
    world = World.from_name(opts.plan, seed=opts.seed)
    world.add_robot(opts.robot, wheelbase_m=opts.wheelbase_m)
    runner = FakeRunner(world, link_dir=opts.link_dir)
    faults = PioneerFaults(opts.corrupt, opts.drop, opts.vanish_after, opts.vanish_for)
    from fakes.pioneer import PioneerConfig

    if "arcos" in opts.devices:
        runner.add(
            PioneerEmulator(
                opts.robot, PioneerConfig(name=opts.robot, baud=opts.baud), faults, seed=opts.seed
            )
        )
    _add_sensors(runner, opts)
    return runner


def _add_sensors(runner: FakeRunner, opts: FakeOptions) -> None:
    """The IR board, the gyro and the GPS (simulated, or a replayed NMEA log)."""
    from drivers.irboard import IrBoardConfig
    from fakes.gps import GpsEmulator, NmeaReplayEmulator
    from fakes.gyro import GyroEmulator
    from fakes.irboard import IrBoardEmulator
    from fakes.world.gps_model import GpsErrorModel
    from fakes.world.gyro_model import GyroErrorModel

    if opts.ir_link not in ("serial", "slcan", "python-can"):
        raise CliError(f"--ir-link {opts.ir_link!r}: choose serial, slcan or python-can")
    if not 1.0 <= opts.gps_rate_hz <= 10.0:
        raise CliError(f"--gps-rate {opts.gps_rate_hz}: a GPS reports at 1 to 10 Hz")
    if not 1 <= opts.gyro_rate_hz <= 1000 or not 1 <= opts.ir_rate_hz <= 1000:
        raise CliError("--gyro-rate / --ir-rate: between 1 and 1000 Hz")
    if "ir" in opts.devices:
        runner.add(
            IrBoardEmulator(
                opts.robot,
                IrBoardConfig(rate_hz=opts.ir_rate_hz, **opts.ir_board),
                link=opts.ir_link,
                can_channel=f"hilnav-{opts.robot}",
                seed=opts.seed + 1,
            )
        )
    if "gyro" in opts.devices:
        runner.add(GyroEmulator(opts.robot, opts.gyro_rate_hz, GyroErrorModel(seed=opts.seed + 2)))
    if "gps" in opts.replay:
        try:
            runner.add(NmeaReplayEmulator(opts.replay["gps"], fast=opts.replay_fast))
        except ValueError as exc:
            raise CliError(str(exc)) from None
    elif "gps" in opts.devices:
        runner.add(GpsEmulator(opts.robot, opts.gps_rate_hz, GpsErrorModel(seed=opts.seed + 3)))


class TruthPublisher:
    """A pseudo-emulator: publishes the world's true pose of one robot on the Zenoh bus
    (``hilnav/<robot>/truth``, msgs.GroundTruth, wall-clock stamps like the drivers') at
    ``rate_hz``, so the daemon logs the truth beside what its sensors say."""

    name = "truth"

    def __init__(self, robot: str, bus, rate_hz: float = 10.0) -> None:  # noqa: ANN001
        self.robot = robot
        self.bus = bus
        self.rate_hz = rate_hz
        self.published = 0
        self._runner = None
        self._due = 0.0

    def start(self, runner) -> None:  # noqa: ANN001
        self._runner = runner

    def tick(self, dt: float) -> None:
        if self._runner is None:
            return
        self._due += dt * self.rate_hz
        if self._due < 1.0:
            return
        self._due -= int(self._due)
        import time

        from msgs import GroundTruth

        r = self._runner.world.robots[self.robot]
        msg = GroundTruth(time.time_ns(), self.robot, r.pose, r.speed_mps, r.yaw_rate_radps)
        try:
            self.bus.publish("truth", msg)
            self.published += 1
        except Exception:  # noqa: BLE001 - the world thread must keep running
            pass

    def stop(self) -> None:
        self._runner = None

    def ports(self) -> dict[str, str]:
        return {}
