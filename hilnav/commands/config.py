"""``hilnav config check FILE``: validate a robot config; ``hilnav config example``;
``hilnav config reference``: the configuration reference as Markdown."""

from __future__ import annotations

import argparse
import sys

from hilnav.errors import CliError


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "config",
        help="check a robot config file, or print the example or the reference",
        description="Robot configuration (TOML). 'check FILE' validates it and says what it "
        "will run; 'example' prints the commented defaults to start from; 'reference' prints "
        "every key with its type, default and check as Markdown (docs/configuration.md).",
    )
    csub = p.add_subparsers(dest="config_command", metavar="ACTION")
    c = csub.add_parser("check", help="validate FILE: one clear message if anything is wrong")
    c.add_argument("file", help="robot TOML file")
    c.set_defaults(func=check)
    e = csub.add_parser("example", help="print the example config (the embedded defaults)")
    e.set_defaults(func=example)
    r = csub.add_parser("reference", help="print the configuration reference (Markdown)")
    r.set_defaults(func=reference)
    p.set_defaults(func=lambda args: (p.print_help(), 2)[1])


def check(args: argparse.Namespace) -> int:
    from hilnav.config import ConfigError, load_config, summary

    try:
        cfg = load_config(args.file)
    except ConfigError as exc:
        raise CliError(str(exc)) from None
    print(f"{args.file}: ok")
    print(summary(cfg))
    return 0


def example(args: argparse.Namespace) -> int:
    from hilnav.config import default_toml_path

    sys.stdout.write(default_toml_path().read_text(encoding="utf-8"))
    return 0


def reference(args: argparse.Namespace) -> int:
    from hilnav.config.reference import reference as markdown

    sys.stdout.write(markdown())
    return 0
