"""Benchmark: ``hilnav fleet`` at 3, 10 and 20 robots, this checkout beside the old fleet,
in one run.

For each robot count (``--robots 3,10,20``) and ``--duration`` simulated seconds
(default 20) at real time (rate 1), runs:

- ``new``: ``hilnav fleet`` of this checkout: robots on the daemon's runtime, shared over
  one host process per core (one Zenoh session each), clients of one Zenoh router on
  loopback; with the comparison localizers (the paper's EKF, single CP), as the old fleet
  ran them;
- ``new-bare``: the same without the comparison localizers (``--no-reference``): the
  robots' own runtime only;
- ``old``: the fleet of ``--baseline`` (default 631dff7, the last commit with one process
  per robot and a peer-to-peer mesh), exported with ``git archive`` to a temporary
  directory; its 12-robot cap is lifted in that copy so that it can run 20. ``--baseline
  main`` compares with main the same way. A variant may be named several times
  (``new,old,new,old``): the runs alternate, side by side.

Per run: the real-time factor (simulated seconds per wall second of the stepping: from
the command's "fleet:" line, printed at the start, to its first result line), the CPU
seconds of every process of the run (start-up included; the command's rusage with its
children's), the cores that makes over the command's wall time, and, for the new fleet,
its own figures over the stepping only (``run_cores``: the hosts' and router's CPU per
wall second; ``cpu_per_sim_s``: the same per simulated second, the cores real time
needs; the p99 age of a peer's box when handled; the worst lateness of a step).
The machine's load (``/proc/loadavg``) is read before and after each run: the machine
is shared, so ratios measured side by side are what count. The LAST line is a JSON
object with every run.

    python bench/fleet.py [--robots 3,10,20] [--duration 20] [--variants new,new-bare,old]
"""

from __future__ import annotations

import argparse
import json
import os
import re
import select
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
BASELINE = "631dff7"


def loadavg() -> list[float]:
    return [float(v) for v in Path("/proc/loadavg").read_text().split()[:3]]


def export_baseline(rev: str, into: Path) -> Path:
    """``rev``'s tree in ``into`` (git archive), its --robots cap lifted."""
    into.mkdir(parents=True, exist_ok=True)
    arch = subprocess.run(
        ["git", "-C", str(ROOT), "archive", "--format=tar", rev],
        capture_output=True,
        check=True,
    )
    subprocess.run(["tar", "-x", "-C", str(into)], input=arch.stdout, check=True)
    cmd = into / "hilnav" / "commands" / "fleet.py"
    text = cmd.read_text()
    cmd.write_text(re.sub(r"args\.robots > 12", "args.robots > 100000", text))
    return into


def run_fleet(
    cwd: Path, robots: int, duration: float, extra: list[str], out: Path
) -> dict[str, Any]:
    """One ``hilnav fleet`` run in ``cwd`` (a checkout); its figures."""
    env = dict(os.environ, PYTHONPATH=str(cwd), PYTHONUNBUFFERED="1")
    cmd = [sys.executable, "-m", "hilnav", "fleet", "--robots", str(robots), "--duration",
           str(duration), "--out", str(out), *extra]  # fmt: skip
    load0 = loadavg()
    t_start = time.time()
    proc = subprocess.Popen(cmd, cwd=cwd, env=env, stdout=subprocess.PIPE, text=True)
    assert proc.stdout is not None
    t_go = t_first = None
    lines: list[str] = []
    deadline = t_start + 60 + 10 * duration * max(1, robots / 3)
    eof = False
    while time.time() < deadline and not eof:
        r, _, _ = select.select([proc.stdout], [], [], 1.0)
        if not r:
            continue
        line = proc.stdout.readline()
        if not line:
            eof = True
            break
        lines.append(line)
        if line.startswith("fleet:") and t_go is None:
            t_go = time.time()
        elif re.match(r"r\d+: ", line) and t_first is None:
            t_first = time.time()
    if not eof:
        proc.kill()
    _, status, ru = os.wait4(proc.pid, 0)  # its rusage includes its children's
    proc.returncode = os.waitstatus_to_exitcode(status)
    proc.stdout.close()
    wall = time.time() - t_start
    res = json.loads(lines[-1]) if lines and lines[-1].startswith("{") else {}
    cpu = ru.ru_utime + ru.ru_stime
    run_wall = (t_first - t_go - 0.5) if t_go and t_first else float("nan")
    return {
        "robots": robots,
        "ok": status == 0 and bool(res),
        "realtime_factor": round(duration / run_wall, 3) if run_wall > 0 else 0.0,
        "cpu_s": round(cpu, 1),
        "cores": round(cpu / wall, 2),
        "wall_s": round(wall, 1),
        "run_cores": res.get("cores"),
        "run_realtime_factor": res.get("realtime_factor"),
        # the cores real time needs: the run's CPU (hosts, routers) per simulated second
        "cpu_per_sim_s": round(res["cores"] / res["realtime_factor"], 3)
        if res.get("realtime_factor")
        else None,
        "box_age_p99_ms": res.get("box_age_p99_ms"),
        "max_lag_s": res.get("max_lag_s"),
        "multi_cp_containment": res.get("multi_cp_containment"),
        "multi_cp_area": res.get("multi_cp_area"),
        "single_cp_area": res.get("single_cp_area"),
        "load_before": load0,
        "load_after": loadavg(),
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robots", default="3,10,20")
    ap.add_argument("--duration", type=float, default=20.0)
    ap.add_argument("--variants", default="new,new-bare,old")
    ap.add_argument("--baseline", default=BASELINE, help="git revision of the old fleet")
    args = ap.parse_args(argv)
    counts = [int(n) for n in args.robots.split(",")]
    variants = args.variants.split(",")
    runs: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory(prefix="hilnav-bench-fleet-") as tmp:
        base = export_baseline(args.baseline, Path(tmp) / "old") if "old" in variants else None
        for n in counts:
            for i, v in enumerate(variants):
                cwd = base if v == "old" else ROOT
                extra = ["--no-reference"] if v == "new-bare" else []
                out = Path(tmp) / f"{v}-{n}-{i}"
                assert cwd is not None
                r = {"variant": v, **run_fleet(cwd, n, args.duration, extra, out)}
                runs.append(r)
                print(
                    f"{v:9s} {n:3d} robots: real-time factor {r['realtime_factor']:5.2f}  "
                    f"CPU {r['cpu_s']:6.1f} s  cores {r['cores']:4.2f} (run {r['run_cores']})  "
                    f"CPU/sim s {r['cpu_per_sim_s']}  "
                    f"box age p99 {r['box_age_p99_ms']} ms  contained {r['multi_cp_containment']}"
                    f"  load {r['load_before'][0]:.1f}->{r['load_after'][0]:.1f}",
                    flush=True,
                )
    print()
    print(f"{'variant':9s} {'robots':>6s} {'RTF':>6s} {'CPU s':>7s} {'cores':>6s} "
          f"{'run cores':>9s} {'age p99 ms':>10s} {'load':>5s}")  # fmt: skip
    for r in runs:
        print(
            f"{r['variant']:9s} {r['robots']:6d} {r['realtime_factor']:6.2f} {r['cpu_s']:7.1f} "
            f"{r['cores']:6.2f} {str(r['run_cores']):>9s} {str(r['box_age_p99_ms']):>10s} "
            f"{r['load_before'][0]:5.1f}"
        )
    print(json.dumps({"duration_s": args.duration, "baseline": args.baseline,
                      "cpus": os.cpu_count(), "runs": runs}))  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
