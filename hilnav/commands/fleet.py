"""``hilnav fleet --robots N --scenario paper``: cooperative CP localization with N robots,
each the daemon's runtime (:class:`hilnav.runtime.RobotRuntime`), meeting through Zenoh
routers.

The robots are shared out over ``--hosts`` processes (:mod:`hilnav.fleet.host`; default
one per core: a host steps its robots in one thread, so more hosts than cores only
compete for them), each host with one Zenoh session in client mode for its robots,
connected only to the routers: ``--routers K`` ``hilnav router`` processes started on loopback (each
connected to the ones before), or the routers given by ``--connect`` or by the base
config's ``[zenoh] connect`` (then none is started). Each robot runs the scenario's
devices through its runtime (CP localization with the peers' boxes and its range-bearing
scans of them), logs to ``<out>/<robot>.mcap``, and drops a peer whose token goes or
whose boxes stop for ``peer_timeout_s``. ``--kill r3@2.0`` SIGKILLs robot r3 (it gets a
host process of its own) 2 s of wall time after the start; ``--kill router1@5`` a
router. The command prints one line per robot and, last, a JSON object: the figures of
bench/cooperative_cp.py pooled over the surviving robots, the peers each dropped, the
real-time factor, the CPU used and the age of the peers' boxes when handled.

``--scenario mrclam --data DIR [--start S]``: the robots are the first N recorded robots
of an MRCLAM run (real data, :mod:`hilnav.fleet.mrclam`), each replaying its odometry and
camera through the real-robot CP and the MRCLAM EKF; their figures are the CP boxes'
containment and areas against the motion capture (the scenario's ``pool``).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import tempfile
import time
from pathlib import Path
from typing import Any

from hilnav.errors import CliError


def register(sub: argparse._SubParsersAction) -> None:
    from hilnav.fleet.scenarios import SCENARIOS

    p = sub.add_parser(
        "fleet",
        help="run N robots (the daemon's runtime) meeting through Zenoh routers",
        description="Cooperative CP localization with N robots: each runs the daemon's runtime "
        "(CP localization service, peers, Zenoh session, MCAP log <out>/<robot>.mcap) fed by "
        "the scenario's simulated devices (or a data set's recorded robots: --scenario "
        "mrclam --data DIR), in real time. Robots are shared out over host "
        "processes and reach each other only through Zenoh routers (started here on loopback "
        "unless --connect or the config names some). A peer whose token goes or whose boxes "
        "stop is dropped until it returns. Prints one line per robot and, last, a JSON summary.",
    )
    p.add_argument(
        "--robots", type=int, default=3, help="number of robots (paper: 3; mrclam: up to 5)"
    )
    p.add_argument(
        "--scenario",
        default="paper",
        choices=sorted(SCENARIOS),
        help="; ".join(f"{e.name}: {e.doc}" for e in SCENARIOS.values()),
    )
    p.add_argument("--duration", type=float, default=50.0, help="simulated (or recorded) seconds")
    p.add_argument("--rate", type=float, default=1.0, help="simulated seconds per wall second")
    p.add_argument("--seed", type=int, default=1, help="seed of the scenario's errors")
    p.add_argument("--window", type=int, default=40, help="CP sliding window (steps)")
    p.add_argument(
        "--data", default=None, metavar="DIR", help="the recorded run (--scenario mrclam)"
    )
    p.add_argument(
        "--start", type=float, default=0.0, help="seconds of the recorded run skipped (mrclam)"
    )
    p.add_argument("--config", help="the robots' base config (TOML); the scenario sets the rest")
    p.add_argument("--hosts", type=int, default=None, help="host processes (default: one per core)")
    p.add_argument(
        "--routers", type=int, default=1, help="Zenoh routers to start on loopback (1 or more)"
    )
    p.add_argument(
        "--connect",
        action="append",
        default=[],
        metavar="ENDPOINT",
        help="use the router(s) at ENDPOINT (repeatable) instead of starting any",
    )
    p.add_argument(
        "--out", type=Path, default=None, help="directory for the logs (default: a temp dir)"
    )
    p.add_argument("--no-log", action="store_true", help="write no MCAP logs")
    p.add_argument(
        "--no-reference",
        action="store_true",
        help="skip the comparison localizers (paper: its EKF, single CP; mrclam: the EKF)",
    )
    p.add_argument(
        "--kill",
        action="append",
        default=[],
        metavar="NAME@SECONDS",
        help="SIGKILL a robot (e.g. r3@2.0) or a router (router1@5) after SECONDS of wall time",
    )
    p.set_defaults(func=run)


def _parse_kills(items: list[str], names: list[str], routers: int) -> list[tuple[str, float]]:
    known = names + [f"router{i + 1}" for i in range(routers)]
    out = []
    for it in items:
        name, _, t = it.partition("@")
        try:
            sec = float(t)
        except ValueError:
            raise CliError(f"--kill {it!r}: use NAME@SECONDS, e.g. r3@2.0") from None
        if name not in known:
            raise CliError(f"--kill {it!r}: no robot or router {name!r}; known: {', '.join(known)}")
        out.append((name, sec))
    return out


def robots_zenoh(base: Any, connect: list[str]) -> Any:
    """The robots' ZenohSettings: clients of ``connect`` (or of the config's own connect
    endpoints, in its mode), listening nowhere."""
    from hilnav.bus import ZenohSettings

    z: ZenohSettings = base.zenoh.settings()
    if connect:
        z = dataclasses.replace(z, mode="client", connect=tuple(connect))
    if z.config_file:
        z = dataclasses.replace(z, config_file=str(Path(z.config_file).resolve()))
    return dataclasses.replace(z, listen=())


def run(args: argparse.Namespace) -> int:
    from hilnav.config import ConfigError, load_config
    from hilnav.config.loader import endpoint_problem
    from hilnav.fleet.scenarios import SCENARIOS, ScenarioArgs

    entry = SCENARIOS[args.scenario]
    if args.robots < 1 or (entry.max_robots is not None and args.robots > entry.max_robots):
        top = entry.max_robots if entry.max_robots is not None else "any number"
        raise CliError(f"--robots {args.robots}: use 1 to {top} with --scenario {entry.name}")
    if args.rate <= 0 or args.duration <= 0:
        raise CliError("--rate and --duration must be > 0")
    for ep in args.connect:
        if endpoint_problem(ep):
            raise CliError(f"--connect {ep!r}: {endpoint_problem(ep)}")
    try:
        base = load_config(args.config)
    except ConfigError as exc:
        raise CliError(str(exc)) from None
    connect = list(args.connect) or list(base.zenoh.connect)
    routers = 0 if connect else max(1, args.routers)
    sargs = ScenarioArgs(
        args.robots, args.duration, args.seed, args.window, args.data or "", args.start
    )
    try:
        names = entry.robot_names(sargs)
    except ValueError as exc:
        raise CliError(str(exc)) from None
    kills = _parse_kills(args.kill, names, routers)
    out = (args.out or Path(tempfile.mkdtemp(prefix="hilnav-fleet-"))).resolve()
    out.mkdir(parents=True, exist_ok=True)
    for f in [*(out / f"{n}.json" for n in names), *out.glob("host-*.json")]:
        f.unlink(missing_ok=True)  # a previous run's figures must not pass for this one's
    res = launch(args, base, names, connect, routers, kills, out)
    print(json.dumps(res))
    return 0


def launch(
    args: argparse.Namespace,
    base: Any,
    names: list[str],
    connect: list[str],
    routers: int,
    kills: list[tuple[str, float]],
    out: Path,
) -> dict[str, Any]:
    from hilnav.bus import free_tcp_port
    from hilnav.fleet.launch import (
        ROUTER_READY,
        Fleet,
        LaunchError,
        host_command,
        router_command,
        share,
    )

    fleet = Fleet()
    hosts = args.hosts or min(len(names), os.cpu_count() or 1)
    groups = share(names, hosts, [k for k, _ in kills if k in names])
    wall = args.duration / args.rate
    try:
        eps: list[str] = []
        for i in range(routers):
            ep = f"tcp/127.0.0.1:{free_tcp_port()}"
            fleet.start(f"router{i + 1}", "router", router_command([ep], eps), ready=ROUTER_READY)
            eps.append(ep)
        zs = dataclasses.asdict(robots_zenoh(base, connect or eps))
        opts = dict(
            scenario=args.scenario, robots=args.robots, seed=args.seed, duration=args.duration,
            rate=args.rate, window=args.window, config=args.config, out=out,
            no_log=args.no_log, no_reference=args.no_reference,
            data=str(Path(args.data).resolve()) if args.data else None, start=args.start or None,
        )  # fmt: skip
        for i, members in enumerate(groups):
            cmd = host_command(f"h{i + 1}", members, zs, **opts)
            fleet.spawn(f"h{i + 1}", "host", cmd, members=members)
        for h in fleet.hosts:  # they start together
            fleet.wait_ready(h, f"READY {h.name}")
        t0 = time.time() + 0.5
        fleet.go(t0)
        where = ", ".join(connect or eps)
        print(f"fleet: {len(names)} robots on {len(groups)} hosts via {where}; logs in {out}")
        fleet.supervise(kills, t0, t0 + 10 * wall + 60.0, say=lambda m: print(m, flush=True))
        router_cpu = {k: v for k, v in fleet.cpu_s().items() if k.startswith("router")}
        fleet.finish()
    except LaunchError as exc:
        raise CliError(str(exc)) from None
    finally:
        fleet.reap()
    return summarize(out, names, args.duration, router_cpu, args.scenario)


def _paper_line(r: dict[str, Any]) -> str:
    drops = [e for e in r["peer_events"] if not e[2]]
    dropped = ", ".join(f"{e[1]} ({e[3]})" for e in drops) or "none"
    return (
        f"{r['robot']}: multi CP area {r['multi_cp_area']:.2f} m^2 s, contained "
        f"{r['multi_cp_contained']}/{r['steps']}, peer boxes {r['peer_boxes_received']}, "
        f"dropped {dropped}"
    )


def summarize(
    out: Path,
    names: list[str],
    sim_s: float,
    extra_cpu: dict[str, float],
    scenario: str = "paper",
) -> dict[str, Any]:
    """The run's JSON from the robots' and hosts' files (and the routers' CPU); the
    scenario's entry says how its robots' figures are pooled and printed."""
    from hilnav.fleet.scenarios import SCENARIOS
    from hilnav.fleet.score import percentile, pooled

    entry = SCENARIOS[scenario]
    pool, line = entry.pool or pooled, entry.line or _paper_line
    results = []
    for name in names:
        f = out / f"{name}.json"
        if not f.is_file():
            print(f"{name}: no result (killed or failed)")
            continue
        r = json.loads(f.read_text())
        results.append(r)
        print(line(r))
    if not results:
        raise CliError("no robot finished; nothing to report")
    hosts = [json.loads(f.read_text()) for f in sorted(out.glob("host-*.json"))]
    res = pool(results)
    res["integrity_alarms"] = sum(r.get("integrity_alarms", 0) for r in results)
    res["robots"] = [r["robot"] for r in results]
    res["dropped"] = {
        r["robot"]: sorted({e[1] for e in r["peer_events"] if not e[2]}) for r in results
    }
    ages = [a for r in results for a in r["box_age_ms"]]
    res["box_age_p50_ms"] = round(percentile(ages, 50), 2)
    res["box_age_p99_ms"] = round(percentile(ages, 99), 2)
    wall = max((h["wall_s"] for h in hosts), default=0.0)
    cpu = sum(h["cpu_s"] for h in hosts) + sum(extra_cpu.values())
    res["realtime_factor"] = round(sim_s / wall, 3) if wall else 0.0
    res["cores"] = round(cpu / wall, 3) if wall else 0.0
    res["max_lag_s"] = max((h["max_lag_s"] for h in hosts), default=0.0)
    res["hosts"] = len(hosts)
    res["steps_per_second"] = round(sum(r["steps"] for r in results) / max(wall, 1e-9), 1)
    res["logs"] = sorted(str(p) for p in out.glob("*.mcap"))
    return res
