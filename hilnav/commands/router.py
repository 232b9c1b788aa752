"""``hilnav router``: a Zenoh router (Zenoh's own router mode, in this process) that
robots on other hosts connect to, so they reach each other through it rather than
directly.

Its Zenoh config is built like a robot's (:class:`hilnav.bus.ZenohSettings`): explicit
``listen`` endpoints (default ``tcp/127.0.0.1:7447``), ``connect`` endpoints of other
routers, multicast scouting off; ``--config`` gives the base: a native Zenoh JSON5 file,
passed through untouched, or a robot TOML whose ``[zenoh]`` table is used (its
``access_control``, ``tls``, ``usrpwd`` and ``extra`` included). The command line's
endpoints replace the config's; the mode is always ``router``. It runs until
SIGINT/SIGTERM (or ``--seconds``).
"""

from __future__ import annotations

import argparse
import dataclasses
import signal
import threading
from pathlib import Path

from hilnav.errors import CliError

DEFAULT_LISTEN = "tcp/127.0.0.1:7447"


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "router",
        help="run a Zenoh router that robots connect to ([zenoh] connect)",
        description="Run a Zenoh router (Zenoh's router mode). Robots whose [zenoh] connect "
        "names it (mode client, or peer) reach each other through it; give a fleet two "
        "routers (the second connecting to the first) and list both in the robots' connect, and "
        "the second takes over when the first goes. Multicast scouting is off; the "
        "endpoints are explicit.",
    )
    p.add_argument(
        "--listen",
        action="append",
        default=[],
        metavar="ENDPOINT",
        help=f"where robots connect (repeatable; default {DEFAULT_LISTEN} unless --config "
        "gives listen endpoints)",
    )
    p.add_argument(
        "--connect",
        action="append",
        default=[],
        metavar="ENDPOINT",
        help="another router to connect to (repeatable)",
    )
    p.add_argument(
        "--config",
        metavar="FILE",
        help="base config: a Zenoh JSON5 file (.json5/.json), or a robot TOML whose [zenoh] "
        "table is used",
    )
    p.add_argument("--seconds", type=float, default=None, help="stop after S seconds")
    p.set_defaults(func=run)


def router_settings(listen: list[str], connect: list[str], config: str | None):
    """The router's ZenohSettings; CliError naming a bad endpoint or config."""
    from hilnav.bus import ZenohSettings
    from hilnav.config import ConfigError, load_config
    from hilnav.config.loader import endpoint_problem

    for opt, eps in (("--listen", listen), ("--connect", connect)):
        for ep in eps:
            problem = endpoint_problem(ep)
            if problem:
                raise CliError(f"{opt} {ep!r}: {problem}")
    if config and Path(config).suffix == ".toml":
        try:
            base = load_config(config).zenoh.settings()
        except ConfigError as exc:
            raise CliError(str(exc)) from None
    elif config:
        if not Path(config).is_file():
            raise CliError(f"--config {config!r}: no such file (a Zenoh JSON5 or a robot TOML)")
        base = ZenohSettings(config_file=config)
    else:
        base = ZenohSettings(listen=(DEFAULT_LISTEN,))
    return dataclasses.replace(
        base,
        mode="router",
        listen=tuple(listen) or base.listen or ((DEFAULT_LISTEN,) if not config else ()),
        connect=tuple(connect) or base.connect,
    )


def run(args: argparse.Namespace) -> int:
    import zenoh

    from hilnav.bus import zenoh_problem

    settings = router_settings(args.listen, args.connect, args.config)
    try:
        session = zenoh.open(settings.to_zenoh())
    except ValueError as exc:
        raise CliError(str(exc)) from None
    except zenoh.ZError as exc:
        raise CliError(f"cannot start the router: {zenoh_problem(exc)}") from None
    stop = threading.Event()
    signal.signal(signal.SIGINT, lambda *_: stop.set())
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    where = ", ".join(settings.listen) or "the endpoints of " + str(args.config)
    print(f"hilnav router: listening on {where} (zid {session.zid()})", flush=True)
    try:
        stop.wait(args.seconds)
    finally:
        session.close()
    print("hilnav router: stopped", flush=True)
    return 0
