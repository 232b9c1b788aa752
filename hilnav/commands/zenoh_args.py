"""The ``--connect``/``--listen ENDPOINT`` options of the commands that join the bus by
themselves (``hilnav view``, ``hilnav play``), and the Zenoh session they describe."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from hilnav.errors import CliError

if TYPE_CHECKING:
    from hilnav.bus import Bus, ZenohSettings

DEFAULT_CONNECT = "tcp/127.0.0.1:7447"  # where `hilnav run` listens by default


def add_zenoh_args(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--connect",
        action="append",
        default=[],
        metavar="ENDPOINT",
        help="Zenoh endpoint to connect to, e.g. tcp/127.0.0.1:7447 (repeatable; default: "
        f"{DEFAULT_CONNECT} unless --listen is given)",
    )
    p.add_argument(
        "--listen",
        action="append",
        default=[],
        metavar="ENDPOINT",
        help="Zenoh endpoint to listen on, for robots that connect here (repeatable)",
    )


def zenoh_settings(args: argparse.Namespace) -> ZenohSettings:
    """Peer mode on the given endpoints, multicast scouting off; CliError on a bad one."""
    from hilnav.bus import ZenohSettings
    from hilnav.config.loader import endpoint_problem

    connect = list(args.connect) or ([] if args.listen else [DEFAULT_CONNECT])
    for opt, eps in (("--connect", connect), ("--listen", args.listen)):
        for ep in eps:
            problem = endpoint_problem(ep)
            if problem:
                raise CliError(f"{opt} {ep!r}: {problem}")
    return ZenohSettings(listen=tuple(args.listen), connect=tuple(connect))


def open_bus(name: str, settings: ZenohSettings) -> Bus:
    """A :class:`hilnav.bus.Bus` without a fleet filter; CliError if Zenoh refuses."""
    from hilnav.bus import Bus, zenoh_problem

    try:
        return Bus(name, settings)
    except Exception as exc:
        raise CliError(f"cannot open the Zenoh session: {zenoh_problem(exc)}") from None
