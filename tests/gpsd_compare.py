"""Compare the NMEA codec with gpsd on one of gpsd's regression logs (``X.log`` + ``X.log.chk``).

gpsd's ``.chk`` holds, interleaved with the log's sentences, the JSON gpsd printed. A gpsd
epoch is a time (the TPV objects that have one; several TPVs of one time: the last one);
ours are the fixes with that ``time_utc`` (several: the last one). A gpsd time 1024 weeks
after ours counts as the same (gpsd's week-rollover correction). SKY objects carry no
time: each belongs to the epoch of the last sentence before it that gives a time of day
(without sentences in the ``.chk``: to the next timed TPV); the codec reports a sky when
it changes, so its sky at an epoch is the last one reported up to that epoch's time.

Each field is compared where gpsd or the codec has it, as gpsd's regression compares
its output: to the precision gpsd prints (one unit of its last digit: 1e-9 degrees,
1e-4 m altitude, 1e-3 m/s speed, 1e-4 degrees track, 1e-3 m/s climb, 1e-3 m eph/epv),
integers exactly. A field one side has and the other lacks does not match. ``time``
counts gpsd epochs the codec also reports.
"""

from __future__ import annotations

import datetime as dt
import json
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path

from drivers.nmea import ROLLOVER_S, NmeaCodec
from drivers.nmea.fields import hhmmss_ns
from msgs import GpsFix, GpsSky

# gpsd TPV key -> (GpsFix attribute, tolerance); None: compared exactly
TPV_FIELDS: dict[str, tuple[str, float | None]] = {
    "mode": ("mode", None),
    "lat": ("lat_deg", 1e-9),
    "lon": ("lon_deg", 1e-9),
    "altMSL": ("alt_msl_m", 1e-4),
    "altHAE": ("alt_hae_m", 1e-4),
    "speed": ("speed_mps", 1e-3),
    "track": ("course_deg", 1e-4),
    "climb": ("climb_mps", 1e-3),
    "eph": ("eph_m", 1e-3),
    "epv": ("epv_m", 1e-3),
}
SKY_FIELDS: dict[str, str] = {"nSat": "n_sat", "uSat": "u_sat"}
# where each sentence type carries its time of day (field index after the address)
_TIME_FIELD = {"GGA": 0, "RMC": 0, "GLL": 4, "GNS": 0, "ZDA": 0, "GBS": 0, "GST": 0}
_EPS = 1e-9


@dataclass
class Agreement:
    """Per field: (matches, compared); ``misses`` lists the first disagreements."""

    counts: dict[str, list[int]] = field(default_factory=dict)
    misses: list[str] = field(default_factory=list)

    def count(self, name: str, ok: bool, what: str) -> None:
        c = self.counts.setdefault(name, [0, 0])
        c[0] += ok
        c[1] += 1
        if not ok and len(self.misses) < 20:
            self.misses.append(what)

    def fraction(self, name: str) -> float:
        ok, n = self.counts.get(name, (0, 0))
        return ok / n if n else 1.0

    def worst(self) -> float:
        return min((self.fraction(k) for k in self.counts), default=1.0)

    def merge(self, other: Agreement) -> None:
        for k, (ok, n) in other.counts.items():
            c = self.counts.setdefault(k, [0, 0])
            c[0] += ok
            c[1] += n
        self.misses += other.misses[: max(0, 20 - len(self.misses))]

    def table(self) -> str:
        return ", ".join(f"{k} {ok}/{n} ({ok / n:.1%})" for k, (ok, n) in self.counts.items() if n)


def _sentence_tod(line: str) -> int | None:
    """Time of day (ms) a logged sentence gives, None if it gives none."""
    parts = line.split("*", 1)[0].split(",")
    kind = parts[0][3:] if not parts[0].startswith("$P") else parts[0][1:]
    if kind == "PSTI" and len(parts) > 2:
        i = 2
    elif kind in _TIME_FIELD:
        i = _TIME_FIELD[kind] + 1
    else:
        return None
    ns = hhmmss_ns(parts[i]) if i < len(parts) else None
    return None if ns is None else ns // 1_000_000


def _tod(iso: str) -> int:
    t = dt.datetime.fromisoformat(iso.replace("Z", "+00:00"))
    return ((t.hour * 60 + t.minute) * 60 + t.second) * 1000 + t.microsecond // 1000


def expected(chk: str) -> tuple[dict[str, dict], dict[str, dict]]:
    """gpsd's last TPV per time, and its SKY keys (last value per key) per epoch time."""
    tpvs: dict[str, dict] = {}
    skies: list[tuple[int | None, dict]] = []
    tod: int | None = None
    interleaved = False
    for line in chk.splitlines():
        if line.startswith("$"):
            interleaved = True
            tod = _sentence_tod(line) if _sentence_tod(line) is not None else tod
        elif line.startswith("{"):
            obj = json.loads(line)
            if obj.get("class") == "TPV" and "time" in obj:
                tpvs[obj["time"]] = obj
                if not interleaved:
                    skies = [(s if s is not None else _tod(obj["time"]), o) for s, o in skies]
            elif obj.get("class") == "SKY":
                skies.append((tod if interleaved else None, obj))
    by_tod = {_tod(t): t for t in tpvs}
    sky: dict[str, dict] = {}
    for when, obj in skies:
        t = by_tod.get(when) if when is not None else None
        if t is not None:
            sky.setdefault(t, {}).update({k: obj[k] for k in SKY_FIELDS if k in obj})
    return tpvs, sky


def decode(raw: bytes, codec: NmeaCodec | None = None) -> list[GpsFix | GpsSky]:
    """The codec's messages for a log, fed one line at a time (``#`` lines skipped)."""
    codec = codec or NmeaCodec()
    out: list[GpsFix | GpsSky] = []
    for i, line in enumerate(raw.splitlines(keepends=True)):
        if not line.startswith(b"#"):
            out += codec.feed(line, i)
    return out + codec.flush()


def _same(ours: object, theirs: object, tol: float | None) -> bool:
    if ours is None or theirs is None:
        return ours is None and theirs is None
    if tol is None:
        return ours == theirs
    return abs(float(ours) - float(theirs)) <= tol * (1 + _EPS) + _EPS * abs(float(theirs))  # type: ignore[arg-type]


def _last_by_time(msgs: Iterable[GpsFix | GpsSky], cls: type) -> dict[dt.datetime, object]:
    out: dict[dt.datetime, object] = {}
    for m in msgs:
        if isinstance(m, cls) and m.time_utc:
            out[dt.datetime.fromisoformat(m.time_utc.replace("Z", "+00:00"))] = m
    return out


def _at_or_before(by_time: dict[dt.datetime, object], t: dt.datetime) -> object | None:
    """The last message at or before ``t`` (a sky holds until the next one)."""
    best = None
    for when, msg in by_time.items():
        if when <= t and (best is None or when >= best[0]):
            best = (when, msg)
    return None if best is None else best[1]


def compare(log: Path, chk: Path) -> Agreement:
    """Field-by-field agreement of the codec with gpsd on one log."""
    tpvs, skies = expected(chk.read_text(encoding="utf-8", errors="replace"))
    msgs = decode(log.read_bytes())
    fixes, ours_sky = _last_by_time(msgs, GpsFix), _last_by_time(msgs, GpsSky)
    rollover = dt.timedelta(seconds=ROLLOVER_S)
    agree = Agreement()
    for t, tpv in tpvs.items():
        when = dt.datetime.fromisoformat(t.replace("Z", "+00:00"))
        key = when if when in fixes else when - rollover
        fix = fixes.get(key)
        agree.count("time", fix is not None, f"{log.name} {t}: no fix")
        if fix is None:
            continue
        for name, (attr, tol) in TPV_FIELDS.items():
            ours, theirs = getattr(fix, attr), tpv.get(name)
            if ours is None and theirs is None:
                continue
            agree.count(
                name, _same(ours, theirs, tol), f"{log.name} {t} {name}: {ours} vs {theirs}"
            )
        sky = _at_or_before(ours_sky, key)
        for name, attr in SKY_FIELDS.items():
            theirs = skies.get(t, {}).get(name)
            if theirs is None:
                continue
            ours = getattr(sky, attr) if sky is not None else None
            agree.count(name, ours == theirs, f"{log.name} {t} {name}: {ours} vs {theirs}")
    return agree
