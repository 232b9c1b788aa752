"""Sub-commands of the ``hilnav`` CLI, one module each (see ``hilnav.cli``)."""

from __future__ import annotations

import argparse

COMPRESSIONS = ("zstd", "lz4", "none")


def add_compression(p: argparse.ArgumentParser) -> None:
    """The ``--compression`` option of every command that writes an MCAP log."""
    p.add_argument(
        "--compression",
        default="zstd",
        choices=COMPRESSIONS,
        help="MCAP chunk compression (zstd: small files; lz4: faster; none)",
    )
