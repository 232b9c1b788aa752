"""The CLI starts without the heavy libraries: ``hilnav --version`` and ``--help`` (every
sub-command's parser built) import no numpy, scipy, Zenoh, MCAP, python-can or pyserial;
a command loads what it needs when it runs. Checked on ``sys.modules`` in a fresh
interpreter, not timed."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from tests.conftest import ROOT, hilnav_env

HEAVY = ("numpy", "scipy", "zenoh", "mcap", "can", "serial", "matplotlib", "msgs", "drivers")

PROBE = """
import contextlib, io, json, sys
import hilnav.cli
out = io.StringIO()
with contextlib.redirect_stdout(out), contextlib.suppress(SystemExit):
    hilnav.cli.main({argv!r})
heavy = {heavy!r}
print(json.dumps(sorted(m for m in sys.modules if m.split(".")[0] in heavy)))
"""


@pytest.mark.parametrize(
    "argv",
    [
        ["--version"],
        ["--help"],
        ["replay", "--help"],
        ["run", "--help"],
        ["probe", "gps", "-h"],
        ["fleet", "--help"],
        ["router", "--help"],
    ],
)
def test_the_cli_starts_without_heavy_modules(argv):
    code = PROBE.format(argv=argv, heavy=HEAVY)
    proc = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        cwd=ROOT,
        env=hilnav_env(),
        timeout=60,
    )
    assert proc.returncode == 0, proc.stderr
    assert json.loads(proc.stdout.splitlines()[-1]) == []


@pytest.mark.parametrize(
    ("argv", "modules"),
    [
        (["--version"], []),
        (["replay", "--help"], ["replay"]),
        (["import", "--help"], ["importer"]),
        (["fleet", "--help"], ["fleet"]),
        (["router", "--help"], ["router"]),
        (["--help"], "all"),
    ],
)
def test_a_command_loads_only_its_own_module(argv, modules):
    code = PROBE.format(argv=argv, heavy=("hilnav",)).replace(
        'm.split(".")[0] in heavy', 'm.startswith("hilnav.commands.")'
    )
    proc = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT,
        env=hilnav_env(), timeout=60,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    loaded = [m.rsplit(".", 1)[1] for m in json.loads(proc.stdout.splitlines()[-1])]
    if modules == "all":
        assert {"replay", "importer", "run", "fleet", "router"} <= set(loaded)
    else:
        assert loaded == modules
