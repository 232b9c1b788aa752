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
    devices: tuple[str, ...] = ("arcos",)


def build_fakes(opts: FakeOptions) -> FakeRunner:
    """A runner with the world and the requested emulators (not started)."""
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
    world = World.from_name(opts.plan, seed=opts.seed)
    world.add_robot(opts.robot)
    runner = FakeRunner(world, link_dir=opts.link_dir)
    faults = PioneerFaults(opts.corrupt, opts.drop, opts.vanish_after, opts.vanish_for)
    from fakes.pioneer import PioneerConfig

    runner.add(
        PioneerEmulator(
            opts.robot, PioneerConfig(name=opts.robot, baud=opts.baud), faults, seed=opts.seed
        )
    )
    return runner
