"""A benchmark's "before" figures from another checkout of hilnav, measured in the same run.

A speed-up is judged by the old and the new code measured side by side on the same machine
at the same time (a shared machine's load moves every figure). Make a checkout of the old
code, e.g. of the commit a branch started from::

    git worktree add /tmp/before <commit>        # or: git archive <commit> | tar -x -C /tmp/before

and give it to a benchmark that has ``--baseline`` (``bench/codecs.py``,
``bench/victoria_park.py``): between its own rounds it runs a benchmark script in a
subprocess, from that checkout's root, with that checkout's packages, and reads the JSON
object the script prints on its last line. ``bench/codecs.py`` runs itself that way (the
same harness for both codes); ``bench/victoria_park.py`` runs the old checkout's copy
(the whole run, its loop included, is the figure).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path


def run_baseline(checkout: Path, script: str, *args: str) -> dict:
    """The JSON object ``script args`` prints on its last line, run from ``checkout``: a
    relative ``script`` is that checkout's own copy; an absolute one (this checkout's
    benchmark, so both are measured the same way) gets ``HILNAV_BENCH_CODE`` set to the
    checkout, whose packages it must then import instead of its own."""
    path = Path(checkout) / script
    if not (Path(checkout) / "drivers").is_dir() or not path.is_file():
        raise SystemExit(f"--baseline {checkout}: no {script} there (a hilnav checkout?)")
    env = dict(os.environ)
    if Path(script).is_absolute():
        env["HILNAV_BENCH_CODE"] = str(Path(checkout).resolve())
    done = subprocess.run(
        [sys.executable, str(path), *args],
        cwd=checkout,
        capture_output=True,
        text=True,
        check=False,
        env=env,
    )
    lines = done.stdout.strip().splitlines()
    if done.returncode or not lines:
        raise SystemExit(f"baseline {path} failed ({done.returncode}): {done.stderr[-2000:]}")
    return json.loads(lines[-1])


def merge_best(best: dict[str, float], new: dict, keys: list[str]) -> None:
    """``best[k] = max(best[k], new[k])`` for the rates ``keys`` present in ``new``."""
    for k in keys:
        if k in new:
            best[k] = max(best.get(k, 0.0), float(new[k]))
