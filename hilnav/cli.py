"""The ``hilnav`` command line: one sub-command per module in ``hilnav.commands``.

Each command module exposes ``register(subparsers)`` which adds its parser and sets
``func`` to a callable taking the parsed arguments and returning an exit code. The
command modules import only the standard library at the top, their heavy dependencies
(numpy, Zenoh, MCAP, the config) when their command runs; and ``hilnav CMD ...`` imports
only CMD's module (``hilnav --version`` none): the CLI starts at once.
"""

from __future__ import annotations

import argparse
import importlib
import sys
import textwrap

from hilnav import __version__
from hilnav.errors import CliError

# Sub-command modules, in the order ``hilnav --help`` lists them.
COMMANDS: tuple[str, ...] = (
    "hilnav.commands.fake",
    "hilnav.commands.probe",
    "hilnav.commands.demo",
    "hilnav.commands.config",
    "hilnav.commands.run",
    "hilnav.commands.view",
    "hilnav.commands.log",
    "hilnav.commands.map",
    "hilnav.commands.play",
    "hilnav.commands.analyze",
    "hilnav.commands.replay",
    "hilnav.commands.importer",
    "hilnav.commands.fleet",
    "hilnav.commands.router",
)
# Commands whose module has another name.
_MODULE_OF = {"import": "importer"}


class _Formatter(argparse.ArgumentDefaultsHelpFormatter):
    """Help that shows every option's default (unless it is unset, or the help already
    says it), and wraps descriptions line by line (their own line breaks stay)."""

    def _fill_text(self, text: str, width: int, indent: str) -> str:
        return "\n".join(
            textwrap.fill(line, width, initial_indent=indent, subsequent_indent=indent)
            for line in text.splitlines()
        )

    def _get_help_string(self, action: argparse.Action) -> str | None:
        text = action.help or ""
        if "default" in text or action.default in (None, False, [], argparse.SUPPRESS):
            return action.help
        return super()._get_help_string(action)


class _Parser(argparse.ArgumentParser):
    """Every ``hilnav`` parser, sub-commands' included (argparse makes them of the
    parent's class), shows its defaults in ``--help``."""

    def __init__(self, *args, **kwargs) -> None:
        kwargs.setdefault("formatter_class", _Formatter)
        super().__init__(*args, **kwargs)


def _modules_for(argv: list[str] | None) -> tuple[str, ...]:
    """The command modules ``argv`` needs: the named command's alone, none for a bare
    ``--version``, every one otherwise (``--help``, no or an unknown command)."""
    args = sys.argv[1:] if argv is None else argv
    first = next((a for a in args if not a.startswith("-")), None)
    if first is None:
        helping = any(a in ("-h", "--help") for a in args)
        return () if "--version" in args and not helping else COMMANDS
    if any(a in ("-h", "--help") for a in args[: args.index(first)]):
        return COMMANDS
    module = f"hilnav.commands.{_MODULE_OF.get(first, first)}"
    return (module,) if module in COMMANDS else COMMANDS


def build_parser(argv: list[str] | None = None) -> argparse.ArgumentParser:
    """The parser, with the sub-commands ``argv`` needs (every one when None)."""
    parser = _Parser(
        prog="hilnav",
        description="Drivers, emulated devices and navigation for a Pioneer 3-DX with cheap sensors.",
    )
    parser.add_argument("--version", action="version", version=f"hilnav {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMANDS if argv is None else _modules_for(argv):
        importlib.import_module(name).register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    if argv is None:
        argv = sys.argv[1:]
    parser = build_parser(argv)
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    from hilnav.heap import keep_heap_slack

    keep_heap_slack()  # numpy's per-scan arrays without page faults (hilnav.heap)
    try:
        return int(args.func(args) or 0)
    except CliError as exc:
        print(f"hilnav {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:  # a file that cannot be read or written: say which and why
        name = exc.filename or ""
        what = f"{name}: {exc.strerror}" if name and exc.strerror else str(exc)
        print(f"hilnav {args.command}: error: {what}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
