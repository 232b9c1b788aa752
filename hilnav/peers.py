"""Which fleet robots count as present: by their liveliness token and by their data.

Pure (the caller passes the monotonic time). A peer is admitted when its data or its
token arrives; it is dropped when its token goes away (Zenoh's lease: seconds) or when
nothing has come from it for ``timeout_s`` (a frozen or cut-off peer whose token Zenoh
still keeps), and admitted again when its data returns. The daemon and the fleet robots
both use this table, and tell their localizer to forget a dropped peer's box.
"""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class PeerTable:
    timeout_s: float = 1.0
    last_seen: dict[str, float] = field(default_factory=dict)
    dropped: list[tuple[str, str]] = field(default_factory=list)  # (robot, why), in order

    @property
    def alive(self) -> set[str]:
        return set(self.last_seen)

    def seen(self, robot: str, now: float) -> bool:
        """Data from ``robot`` at ``now``; True if it was not present before."""
        new = robot not in self.last_seen
        self.last_seen[robot] = now
        return new

    def token(self, robot: str, alive: bool, now: float) -> bool:
        """Its liveliness token appeared or went; True if it was dropped by this."""
        if alive:
            self.last_seen.setdefault(robot, now)
            return False
        if self.last_seen.pop(robot, None) is None:
            return False
        self.dropped.append((robot, "token gone"))
        return True

    def expire(self, now: float) -> list[str]:
        """The peers silent for more than ``timeout_s``, now dropped."""
        gone = [r for r, t in self.last_seen.items() if now - t > self.timeout_s]
        for r in gone:
            del self.last_seen[r]
            self.dropped.append((r, f"silent for {self.timeout_s:g} s"))
        return gone
