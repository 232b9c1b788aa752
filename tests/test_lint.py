"""The README's promise: the test command also runs ruff and import-linter on the checkout."""

import subprocess
import sys
from importlib.metadata import entry_points
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _run(*cmd: str) -> subprocess.CompletedProcess:
    return subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=300)


def test_ruff_check_is_clean():
    res = _run(sys.executable, "-m", "ruff", "check", ".")
    assert res.returncode == 0, res.stdout + res.stderr


def test_import_linter_keeps_the_layers():
    """Run the ``lint-imports`` console script's own entry point with this interpreter."""
    (ep,) = [e for e in entry_points(group="console_scripts") if e.name == "lint-imports"]
    code = f"import sys; from {ep.module} import {ep.attr} as main; sys.exit(main())"
    res = _run(sys.executable, "-c", code, "--no-cache")
    assert res.returncode == 0, res.stdout + res.stderr
    assert "0 broken" in res.stdout and "KEPT" in res.stdout, res.stdout
