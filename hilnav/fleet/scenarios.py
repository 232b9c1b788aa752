"""The scenarios ``hilnav fleet --scenario NAME`` can run, by name.

A scenario is the world of a fleet run: the robots, their simulated (or recorded)
devices, the truth, and what each robot's :class:`hilnav.runtime.RobotRuntime` is
configured to run. Every host process rebuilds it from the same arguments (it must be
deterministic for them). To add one, write a class with the members of
:class:`FleetScenario` and :func:`register` a builder for it::

    register(ScenarioEntry("mine", "what it is", lambda a: MyScenario(a.robots, ...)))

The entry's ``max_robots`` (None: no limit of the scenario's own) is checked by the
command before anything starts. Importing this module loads no scenario (``hilnav
--help`` lists them): a builder imports its scenario when it is called.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol

if TYPE_CHECKING:  # the command line lists the scenarios without loading them
    from hilnav.config import RobotConfig
    from msgs import Pose2D, PoseBox, RelativeScan


class RobotDevices(Protocol):
    """One robot's devices in a scenario, stepped in order from 0."""

    def messages(self, s: int) -> list[tuple[str, Any]]:
        """(topic, msg) of step ``s`` in arrival order, stamped on the run's clock."""
        ...

    def relative_scan(self, s: int, targets: Sequence[str]) -> RelativeScan | None:
        """This robot's range-bearing scan of ``targets`` at step ``s`` (None: none)."""
        ...

    def truth(self, s: int) -> Pose2D:
        """Where the robot really is at step ``s`` (theta continuous)."""
        ...


class Reference(Protocol):
    """Localizers the runtime's cooperative CP is compared with (not part of the robot)."""

    methods: tuple[str, ...]

    def feed(self, msgs: list[tuple[str, Any]]) -> None: ...

    def record(self, truth: Sequence[float], multi: PoseBox) -> None: ...

    def figures(self, dt: float) -> dict[str, Any]: ...


class FleetScenario(Protocol):
    """What a fleet run needs of a scenario. A scenario may also name the class of its
    robots (``robot_class``, the host's :class:`hilnav.fleet.robot.SimRobot` when it does
    not): a subclass that runs another pipeline or steps otherwise."""

    @property
    def names(self) -> list[str]: ...

    @property
    def dt_s(self) -> float: ...

    @property
    def steps(self) -> int: ...

    def config(self, robot: str, base: RobotConfig) -> RobotConfig:
        """``base`` made this robot's (name, fleet, start, the services it runs)."""
        ...

    def devices(self, robot: str, base_ns: int) -> RobotDevices:
        """The robot's devices, their stamps ``base_ns`` + scenario time."""
        ...

    def reference(self, robot: str, cfg: RobotConfig, base_ns: int) -> Reference | None: ...


@dataclass(frozen=True)
class ScenarioArgs:
    """The command line's part of a scenario (the same in every host process)."""

    robots: int
    duration_s: float
    seed: int
    window: int = 40
    data: str = ""  # a data set's directory (recorded robots)
    start_s: float = 0.0  # seconds of the data set skipped


@dataclass(frozen=True)
class ScenarioEntry:
    """A scenario by name: how to build it, and (optional) how to name its robots without
    building it (the command only needs the names)."""

    name: str
    doc: str
    build: Callable[[ScenarioArgs], FleetScenario]
    max_robots: int | None = None
    names: Callable[[ScenarioArgs], list[str]] | None = None
    #: the run's figures from the robots' results (None: the paper's, hilnav.fleet.score)
    pool: Callable[[list[dict[str, Any]]], dict[str, Any]] | None = None
    #: one line about a robot's result (None: the paper's)
    line: Callable[[dict[str, Any]], str] | None = None

    def robot_names(self, args: ScenarioArgs) -> list[str]:
        return self.names(args) if self.names is not None else self.build(args).names


SCENARIOS: dict[str, ScenarioEntry] = {}


def register(entry: ScenarioEntry) -> None:
    SCENARIOS[entry.name] = entry


def build(name: str, args: ScenarioArgs) -> FleetScenario:
    """The scenario ``name`` for ``args``; ValueError naming the known ones."""
    entry = SCENARIOS.get(name)
    if entry is None:
        raise ValueError(f"scenario {name!r}: unknown; known: {', '.join(sorted(SCENARIOS))}")
    return entry.build(args)


def _paper(a: ScenarioArgs) -> FleetScenario:
    from hilnav.fleet.paper import PaperScenario

    return PaperScenario.build(a.robots, a.duration_s, a.seed, a.window)


def _paper_names(a: ScenarioArgs) -> list[str]:
    from fakes.world.paper_scenario import paper_robots

    return [s.name for s in paper_robots(a.robots)]


register(
    ScenarioEntry(
        "paper",
        "the ekf-vs-cp experiment (§2.4): robots on parallel lanes 5 m apart with encoders, "
        "gyro, GPS and a range-bearing sensor seeing the others, every error bounded",
        _paper,
        names=_paper_names,
    )
)


def _mrclam(a: ScenarioArgs) -> FleetScenario:
    from hilnav.fleet.mrclam import MrclamScenario

    return MrclamScenario.build(a.data, a.robots, a.duration_s, a.start_s)


def _mrclam_names(a: ScenarioArgs) -> list[str]:
    from hilnav.fleet.mrclam import fleet_subjects

    return [f"r{n}" for n in fleet_subjects(a.data, a.robots)]


def _mrclam_pool(results: list[dict[str, Any]]) -> dict[str, Any]:
    from hilnav.fleet.mrclam_robot import pool

    return pool(results)


def _mrclam_line(result: dict[str, Any]) -> str:
    from hilnav.fleet.mrclam_robot import line

    return line(result)


register(
    ScenarioEntry(
        "mrclam",
        "a recorded MRCLAM run (--data DIR, real data): its first N robots, each replaying "
        "its velocity odometry and camera measurements (from --start, at --rate) through "
        "the real-robot CP (and the MRCLAM EKF), scored against the motion capture",
        _mrclam,
        names=_mrclam_names,
        pool=_mrclam_pool,
        line=_mrclam_line,
    )
)
