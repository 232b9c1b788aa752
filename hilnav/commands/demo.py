"""``hilnav demo``: one simulated Pioneer, the daemon, a scripted tour over Zenoh, a report.

1. starts ``hilnav run`` on the embedded defaults (a Zenoh peer on a free loopback port):
   the daemon starts the emulated Pioneer, IR board (on CAN, behind the emulated slcan
   adapter), gyro and GPS on ptys in the office floor plan, and logs everything to MCAP;
2. joins the bus as ``operator`` (a second Zenoh session), waits for the robot's
   liveliness token and first pose, and drives a tour that loops the west room, visits
   the south-east room through a door and comes back over its start (so places are
   revisited), sending ``cmd_vel`` at 10 Hz like a joystick. The operator steers by what
   a person watching the robot sees: the simulator's ground truth (``truth``), or the
   daemon's pose estimate when there is no truth;
3. stops the robot, stops the daemon with SIGTERM (log closed), and analyses the log as
   ``hilnav analyze`` does (hilnav.analysis: PNGs and summary.json), printing a digest
   of its figures (path errors and heading drift, map match ratio, CP box containment);
4. prints where the MCAP, the PNGs and the summary are.
"""

from __future__ import annotations

import argparse
import math
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

from hilnav.errors import CliError

# The tour in the office plan (8.9 x 7.1 m; west room x < 4, doors at x = 4, y 1.5-2.5).
TOUR: tuple[tuple[float, float], ...] = (
    # a loop in the west room, >= 1.2 m from the walls (the Sharp sensors see 1-5.5 m)
    (2.8, 1.3),
    (2.8, 3.9),
    (1.3, 3.9),
    (1.3, 1.3),
    (2.2, 1.3),
    # through the door at (4, 2) into the south-east room, a loop there, and back
    (3.0, 2.0),
    (5.3, 2.0),
    (6.8, 1.6),
    (6.8, 2.4),
    (5.3, 2.4),
    (5.0, 2.0),
    (3.0, 2.0),
    # the west loop again: places seen before
    (2.8, 3.9),
    (1.3, 3.9),
    (1.3, 1.3),
)


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "demo",
        help="the demo: a simulated Pioneer, the daemon, a tour driven over Zenoh, a report",
        description=__doc__.split("\n\n", 1)[1].replace("``", "`") if __doc__ else None,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--out", default="hilnav-demo", help="output directory (default ./hilnav-demo)")
    p.add_argument("--seed", type=int, default=0, help="seed of the simulated world")
    p.add_argument("--speed", type=float, default=0.5, help="cruise speed, m/s")
    p.add_argument(
        "--waypoints",
        "--laps",  # its old name
        dest="waypoints",
        type=int,
        default=len(TOUR),
        help=f"drive only the first N waypoints of the tour (default all {len(TOUR)})",
    )
    p.set_defaults(func=run)


def _say(text: str) -> None:
    print(f"[{time.strftime('%H:%M:%S')}] {text}", flush=True)


class Operator:
    """The user's side: a Zenoh session that watches the robot and sends cmd_vel."""

    def __init__(self, robot: str, port: int) -> None:
        from hilnav.bus import Bus, ZenohSettings

        self.robot = robot
        # gossip (with the daemon's): the operator also reaches the simulator's session
        settings = ZenohSettings(
            listen=("tcp/127.0.0.1:0",),
            connect=(f"tcp/127.0.0.1:{port}",),
            gossip_scouting=True,
        )
        self.bus = Bus("operator", settings, fleet=[robot])
        self.lock = threading.Lock()
        self.pose: Any = None
        self.truth: Any = None
        self.alive = False
        self.bus.subscribe(robot, "pose", self._on_pose)
        self.bus.subscribe(robot, "truth", self._on_truth)
        self.bus.on_liveliness(self._on_alive)

    def _on_pose(self, robot: str, msg: Any) -> None:
        with self.lock:
            self.pose = msg.pose

    def _on_truth(self, robot: str, msg: Any) -> None:
        with self.lock:
            self.truth = msg.pose

    def _on_alive(self, robot: str, alive: bool) -> None:
        if robot == self.robot:
            self.alive = alive

    def where(self) -> Any:
        with self.lock:
            return self.truth if self.truth is not None else self.pose

    def send(self, v: float, w: float) -> None:
        from drivers.clock import now_ns
        from msgs import VelocityCommand

        self.bus.publish_to(
            self.robot, "cmd_vel", VelocityCommand(now_ns(), v, w, source="operator")
        )

    def drive(self, waypoints, speed: float, deadline: float) -> int:
        """Follow the waypoints; returns how many were reached before the deadline."""
        from msgs import wrap_angle

        reached = 0
        for tx, ty in waypoints:
            wp_deadline = min(deadline, time.monotonic() + 40.0)
            while time.monotonic() < wp_deadline:
                p = self.where()
                if p is None:
                    time.sleep(0.1)
                    continue
                dx, dy = tx - p.x, ty - p.y
                if math.hypot(dx, dy) < 0.2:
                    break
                err = wrap_angle(math.atan2(dy, dx) - p.theta)
                w = max(-1.0, min(1.0, 2.5 * err))
                v = 0.0 if abs(err) > 0.25 else speed * math.cos(err) ** 4
                v = min(v, 0.25 + 0.5 * math.hypot(dx, dy))
                self.send(v, w)
                time.sleep(0.1)
            else:
                return reached
            reached += 1
        return reached

    def close(self) -> None:
        self.bus.close()


def _start_daemon(out: Path, port: int, seed: int) -> tuple[subprocess.Popen, Path]:
    cfg = out / "demo-robot.toml"
    cfg.write_text(
        "# written by hilnav demo: the embedded defaults with a free Zenoh port\n"
        f'[zenoh]\nlisten = ["tcp/127.0.0.1:{port}"]\ngossip_scouting = true\n'
        f'[log]\ndir = "{out}"\n'
        f"[simulation]\nseed = {seed}\n"
    )
    log = out / "demo.mcap"
    proc = subprocess.Popen(
        [sys.executable, "-m", "hilnav", "run", "--config", str(cfg), "--log", str(log), "--quiet"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    return proc, log


def _stop_daemon(proc: subprocess.Popen) -> str:
    if proc.poll() is None:
        proc.send_signal(signal.SIGTERM)
    try:
        out, err = proc.communicate(timeout=30)
    except subprocess.TimeoutExpired:
        proc.kill()
        out, err = proc.communicate()
    if proc.returncode != 0:
        raise CliError(f"the daemon exited with {proc.returncode}: {err.strip()[-500:]}")
    return out


def run(args: argparse.Namespace) -> int:
    from hilnav.bus import free_tcp_port

    t0 = time.monotonic()
    out = Path(args.out).resolve()
    out.mkdir(parents=True, exist_ok=True)
    port = free_tcp_port()
    _say(f"starting the daemon on a simulated Pioneer (office plan), Zenoh tcp/127.0.0.1:{port}")
    proc, log = _start_daemon(out, port, args.seed)
    op = None
    try:
        op = Operator("r1", port)
        end = time.monotonic() + 40.0
        while time.monotonic() < end and (not op.alive or op.where() is None):
            if proc.poll() is not None:
                raise CliError(f"the daemon did not start: {proc.stderr.read().strip()[-500:]}")
            time.sleep(0.1)
        if op.where() is None:
            raise CliError("the daemon published no pose within 40 s")
        _say("robot r1 is alive; standing still 2 s (the gyro's bias is measured)")
        time.sleep(2.0)
        _say(
            "driving the tour over cmd_vel (10 Hz), steering on "
            + ("the simulator's truth" if op.truth is not None else "the pose estimate")
        )
        waypoints = TOUR[: max(1, args.waypoints)]
        t_drive = time.monotonic()
        reached = op.drive(waypoints, args.speed, time.monotonic() + 80.0)
        for _ in range(5):
            op.send(0.0, 0.0)
            time.sleep(0.1)
        _say(
            f"tour done: {reached}/{len(waypoints)} waypoints in "
            f"{time.monotonic() - t_drive:.0f} s; stopping the daemon"
        )
    finally:
        if op is not None:
            op.close()
        daemon_out = _stop_daemon(proc)
    for line in daemon_out.strip().splitlines()[-1:]:
        _say(line)
    _say("analysing the log")
    report = analyse(log, out)
    _say(f"done in {time.monotonic() - t0:.0f} s")
    print(f"MCAP log : {log}")
    for png in sorted(out.glob("*.png")):
        print(f"PNG      : {png}")
    print(f"summary  : {report}")
    return 0


def analyse(log: Path, out: Path) -> Path:
    """Analyse the log as ``hilnav analyze`` does, print its digest; returns the JSON path."""
    from hilnav.analysis.analyze import analyze
    from hilnav.analysis.report import digest, write_report

    try:
        result = analyze(log)
    except ValueError as exc:
        raise CliError(f"{log}: {exc}") from None
    summary = write_report(result, out)
    for line in digest(result):
        print(line)
    return Path(summary["summary_json"])
