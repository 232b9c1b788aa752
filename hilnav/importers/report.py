"""What an importer wrote: messages per topic, time span, and the importer's own figures."""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from typing import Any


@dataclass
class ImportReport:
    source: str
    output: str
    robot: str
    counts: Counter = field(default_factory=Counter)
    detections: int = 0
    first_ns: int = 0
    last_ns: int = 0
    extra: dict[str, Any] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        return {
            "source": self.source,
            "output": self.output,
            "robot": self.robot,
            "messages": dict(sorted(self.counts.items())),
            "detections": self.detections,
            "first_ns": self.first_ns,
            "last_ns": self.last_ns,
            "duration_s": round((self.last_ns - self.first_ns) / 1e9, 3),
            **self.extra,
        }
