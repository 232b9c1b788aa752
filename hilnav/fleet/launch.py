"""Starting and supervising the processes of a fleet run: Zenoh routers (``hilnav
router``) and host processes (:mod:`hilnav.fleet.host`), optionally each behind a prefix
(``ip netns exec NS``: bench/fleet_hosts.py).

Every start waits (bounded) for the child's ready line; :meth:`Fleet.supervise` carries
out a kill schedule until every host is done or the deadline; :meth:`Fleet.reap` kills
whatever still runs and waits for all, so nothing outlives the run.
"""

from __future__ import annotations

import json
import os
import select
import signal
import subprocess
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

ROUTER_READY = "hilnav router: listening on"


class LaunchError(RuntimeError):
    """A child did not start: the message says which and what it printed."""


@dataclass
class Child:
    name: str
    kind: str  # "router" or "host"
    proc: subprocess.Popen
    members: list[str] = field(default_factory=list)
    done: bool = False
    killed_at: float | None = None
    cpu0: float = 0.0


def proc_cpu_s(pid: int) -> float:
    """User + system CPU seconds of a live process (0.0 when it is gone)."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return 0.0
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def read_line(proc: subprocess.Popen, timeout_s: float) -> str | None:
    """One line of the child's stdout (stripped), or None at EOF, exit or timeout."""
    deadline = time.monotonic() + timeout_s
    assert proc.stdout is not None
    while time.monotonic() < deadline:
        r, _, _ = select.select([proc.stdout], [], [], 0.2)
        if r:
            line = proc.stdout.readline()
            return line.decode().strip() if line else None
        if proc.poll() is not None:
            return None
    return None


def router_command(listen: Sequence[str], connect: Sequence[str] = ()) -> list[str]:
    cmd = [sys.executable, "-m", "hilnav", "router"]
    for ep in listen:
        cmd += ["--listen", ep]
    for ep in connect:
        cmd += ["--connect", ep]
    return cmd


def host_command(
    host: str, members: Sequence[str], zenoh: dict[str, Any], **opts: Any
) -> list[str]:
    """``python -m hilnav.fleet.host`` for ``members``; ``opts`` are its options by name
    (``True`` for a flag, None or False to leave one out)."""
    cmd = [sys.executable, "-m", "hilnav.fleet.host", "--host", host]
    cmd += ["--members", ",".join(members), "--zenoh", json.dumps(zenoh)]
    for k, v in opts.items():
        if v is None or v is False:
            continue
        cmd.append("--" + k.replace("_", "-"))
        if v is not True:
            cmd.append(str(v))
    return cmd


def share(names: Sequence[str], hosts: int, alone: Sequence[str] = ()) -> list[list[str]]:
    """Robots per host: each of ``alone`` on a host of its own (so killing that process
    kills that robot only), the others dealt round-robin over ``hosts`` hosts."""
    rest = [n for n in names if n not in alone]
    groups: list[list[str]] = [[] for _ in range(max(1, min(hosts, len(rest))))] if rest else []
    for i, n in enumerate(rest):
        groups[i % len(groups)].append(n)
    return groups + [[n] for n in names if n in alone]


class Fleet:
    """The children of one run (routers first, then hosts)."""

    def __init__(self) -> None:
        self.children: list[Child] = []

    @property
    def hosts(self) -> list[Child]:
        return [c for c in self.children if c.kind == "host"]

    @property
    def routers(self) -> list[Child]:
        return [c for c in self.children if c.kind == "router"]

    def spawn(
        self,
        name: str,
        kind: str,
        cmd: list[str],
        *,
        prefix: Sequence[str] = (),
        members: Sequence[str] = (),
        cwd: str | None = None,
    ) -> Child:
        """Start a child (its stdin and stdout are pipes to this process)."""
        proc = subprocess.Popen(
            [*prefix, *cmd], stdin=subprocess.PIPE, stdout=subprocess.PIPE, cwd=cwd
        )
        child = Child(name, kind, proc, list(members))
        self.children.append(child)
        return child

    @staticmethod
    def wait_ready(child: Child, ready: str, timeout_s: float = 90.0) -> None:
        """Wait for the child's stdout line starting with ``ready``; LaunchError if not."""
        line = read_line(child.proc, timeout_s)
        if line is None or not line.startswith(ready):
            raise LaunchError(
                f"{child.kind} {child.name} did not start (got {line!r}); see its stderr above"
            )

    def start(self, name: str, kind: str, cmd: list[str], *, ready: str, **kw: Any) -> Child:
        """:meth:`spawn`, then :meth:`wait_ready`."""
        child = self.spawn(name, kind, cmd, **kw)
        self.wait_ready(child, ready)
        return child

    def go(self, t0: float) -> None:
        """Tell every host to start its step 0 at wall time ``t0``."""
        for c in self.children:
            c.cpu0 = proc_cpu_s(c.proc.pid)
        for h in self.hosts:
            assert h.proc.stdin is not None
            h.proc.stdin.write(f"GO {t0!r}\n".encode())
            h.proc.stdin.flush()

    def kill(self, name: str) -> bool:
        """SIGKILL the child ``name`` (a router, or the host of that robot)."""
        for c in self.children:
            if (c.name == name or name in c.members) and c.proc.poll() is None:
                c.proc.send_signal(signal.SIGKILL)
                c.killed_at = time.time()
                return True
        return False

    def supervise(
        self, kills: Sequence[tuple[str, float]], t0: float, deadline: float, say: Any = print
    ) -> None:
        """Until every host is done (or the deadline): carry out the kill schedule
        (name, seconds after ``t0``)."""
        pending = sorted(kills, key=lambda k: k[1])
        while time.time() < deadline:
            running = [h for h in self.hosts if h.proc.poll() is None and not h.done]
            if not running:
                break
            now = time.time() - t0
            while pending and now >= pending[0][1]:
                victim, _ = pending.pop(0)
                if self.kill(victim):
                    say(f"fleet: killed {victim} at {now:.1f} s")
            outs = [h.proc.stdout for h in running]
            ready, _, _ = select.select(outs, [], [], 0.05)
            for h in running:
                if h.proc.stdout in ready:
                    assert h.proc.stdout is not None
                    line = h.proc.stdout.readline().decode().strip()
                    if line == f"DONE {h.name}" or not line:
                        h.done = True

    def cpu_s(self) -> dict[str, float]:
        """CPU seconds of each live child since :meth:`go`."""
        return {
            c.name: round(proc_cpu_s(c.proc.pid) - c.cpu0, 3)
            for c in self.children
            if c.proc.poll() is None
        }

    def finish(self) -> None:
        """Everyone finished (or died): tell the hosts to close, and wait (bounded)."""
        for h in self.hosts:
            if h.proc.poll() is None and h.proc.stdin is not None:
                try:
                    h.proc.stdin.write(b"STOP\n")
                    h.proc.stdin.flush()
                except OSError:
                    pass
        for h in self.hosts:
            try:
                h.proc.wait(timeout=20)
            except subprocess.TimeoutExpired:
                h.proc.kill()

    def reap(self) -> None:
        """Stop the routers (SIGTERM), kill anything left, wait for every child."""
        for c in self.children:
            if c.proc.poll() is None:
                c.proc.send_signal(signal.SIGTERM if c.kind == "router" else signal.SIGKILL)
        for c in self.children:
            try:
                c.proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                c.proc.kill()
                c.proc.wait(timeout=10)
            for f in (c.proc.stdin, c.proc.stdout):
                if f:
                    f.close()
