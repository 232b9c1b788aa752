"""Raw ADC counts of an IR board -> :class:`msgs.IrScan` (volts, ranges, validity flags).

counts -> volts with the board's reference voltage and resolution; volts -> range through
each channel's Sharp curve (:mod:`drivers.sharp`, the datasheet table or a calibration
table per sensor), flagged ``too_near`` / ``too_far`` / ``no_return`` / ``invalid``
outside 1.0-5.5 m rather than clamped; optionally the median of the last N ranges.
Mounting poses (x, y, yaw in the robot frame) belong to the board's configuration; the
default is the IR-mapping paper's robot: six sensors facing front and sides.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache
from operator import itemgetter

import numpy as np

from drivers.irboard.serialframe import RawSample
from drivers.sharp import STATUS_NAMES, MedianFilter, SharpCurve
from msgs import IrScan
from msgs.construct import positional_constructor

make_scan = positional_constructor(IrScan)

D = math.pi / 180.0
# Six sensors on a Pioneer 3-DX body (x forward, y left, metres; yaw radians).
PAPER_MOUNTS: tuple[tuple[float, float, float], ...] = (
    (0.20, 0.05, 15 * D),
    (0.20, -0.05, -15 * D),
    (0.17, 0.13, 50 * D),
    (0.17, -0.13, -50 * D),
    (0.00, 0.19, 90 * D),
    (0.00, -0.19, -90 * D),
)


@dataclass(frozen=True)
class IrBoardConfig:
    """One ADC board: id, resolution, reference, rate, and per-channel sensors."""

    board_id: int = 1
    adc_bits: int = 10
    vref_v: float = 5.0
    rate_hz: int = 20
    mounts: tuple[tuple[float, float, float], ...] = PAPER_MOUNTS
    curves: tuple[SharpCurve, ...] = ()  # empty: the datasheet curve on every channel
    median_window: int = 1  # 1 = no filter

    def __post_init__(self) -> None:
        if self.adc_bits not in (10, 12):
            raise ValueError(f"ir.adc_bits must be 10 or 12, not {self.adc_bits}")
        if not 1 <= len(self.mounts) <= 8:
            raise ValueError(f"ir.mounts must list 1..8 sensors, not {len(self.mounts)}")
        if self.curves and len(self.curves) != len(self.mounts):
            raise ValueError(
                f"ir.curves has {len(self.curves)} tables for {len(self.mounts)} sensors:"
                " give one per sensor or none"
            )
        if self.vref_v <= 0:
            raise ValueError(f"ir.vref_v must be > 0, not {self.vref_v}")

    @property
    def channels(self) -> int:
        return len(self.mounts)

    def curve(self, i: int) -> SharpCurve:
        return self.curves[i] if self.curves else _DEFAULT_CURVE

    def mounts_array(self) -> np.ndarray:
        return np.asarray(self.mounts, dtype=float).reshape(-1, 3)


_DEFAULT_CURVE = SharpCurve()


@dataclass
class IrConverter:
    """Stateful (median filter) conversion of raw samples into scans.

    Table-driven: at construction every possible count (0 .. 2**adc_bits - 1) is turned
    into volts, range and status once, with the same numpy arithmetic the per-sample
    path uses, so a sample is three table look-ups per channel and the outputs are
    identical. Counts outside the tables (which no decoder yields) take the numpy path.
    """

    config: IrBoardConfig = field(default_factory=IrBoardConfig)
    mismatched: int = 0  # samples whose channel count or resolution differ from the config

    def __post_init__(self) -> None:
        cfg = self.config
        w = cfg.median_window
        self._median = MedianFilter(cfg.channels, w) if w > 1 else None
        self._volts, self._tables, lists = _tables(cfg.adc_bits, cfg.vref_v, cfg.curves)
        # count -> volts, range, status as lists: the one-curve case without a median
        self._lists = lists if self._median is None else None

    def __call__(self, s: RawSample, stamp_ns: int) -> IrScan | None:
        cfg = self.config
        counts = s.counts
        if len(counts) != cfg.channels or s.adc_bits != cfg.adc_bits:
            self.mismatched += 1
            return None
        return self.scan(s, counts, stamp_ns)

    def lookup_lists(self) -> tuple[list, list, list] | None:
        """(volts, ranges, statuses) indexed by count when one curve serves every channel
        and there is no median filter; else None."""
        return self._lists

    def scan_counts(
        self, board_id: int, seq: int, counts: tuple[int, ...], stamp_ns: int
    ) -> IrScan | None:
        """:meth:`__call__` of a decoder's (sequence, counts) at the board's resolution.
        When one curve serves every channel and there is no median filter, one
        ``itemgetter`` of the counts reads the volts, ranges and statuses of all channels
        from the three tables (counts are below 2**adc_bits, the tables' length)."""
        lists = self._lists
        n = len(counts)
        if lists is None or n != self.config.channels or n < 2:
            return self(RawSample(board_id, seq, self.config.adc_bits, counts), stamp_ns)
        get = itemgetter(*counts)
        try:
            volts, ranges, status = get(lists[0]), get(lists[1]), get(lists[2])
        except (IndexError, TypeError):
            return self(RawSample(board_id, seq, self.config.adc_bits, counts), stamp_ns)
        return make_scan(stamp_ns, board_id, seq, ranges, status, volts, counts)

    def scan(self, s: RawSample, counts: tuple[int, ...], stamp_ns: int) -> IrScan:
        """The scan of a sample whose channel count and resolution match the board's."""
        if self._lists is not None and len(counts) > 1:
            raw = tuple(map(int, counts))
            if min(raw) >= 0:
                get = itemgetter(*raw)
                lists = self._lists
                try:
                    volts, ranges, status = get(lists[0]), get(lists[1]), get(lists[2])
                except IndexError:
                    return self._convert(s, stamp_ns)
                return make_scan(stamp_ns, s.board_id, s.seq, ranges, status, volts, raw)
        try:
            volts = tuple(map(self._volts.__getitem__, counts))
            if len(self._tables) == 1:
                rt, st = self._tables[0]
                ranges = tuple(map(rt.__getitem__, counts))
                status = tuple(map(st.__getitem__, counts))
            else:
                ranges = tuple(t[0][c] for t, c in zip(self._tables, counts, strict=True))
                status = tuple(t[1][c] for t, c in zip(self._tables, counts, strict=True))
        except (KeyError, TypeError):
            return self._convert(s, stamp_ns)
        if self._median is not None:
            return self._filtered(s, stamp_ns, ranges, volts, status)
        raw = tuple(map(int, counts))
        return IrScan(stamp_ns, s.board_id, s.seq, ranges, status, volts, raw)  # type: ignore[arg-type]

    def _filtered(self, s: RawSample, stamp_ns: int, ranges, volts, status) -> IrScan:
        """The median of the channel's last ranges; a channel whose reading is not "ok"
        counts as missing, and reads "ok" again when its median is finite."""
        names = [STATUS_NAMES[STATUS_NAMES.index(x)] for x in status]
        ok = [float(r) if n == "ok" else math.nan for r, n in zip(ranges, names, strict=True)]
        med = self._median(ok)  # type: ignore[misc]
        return IrScan(
            stamp_ns=stamp_ns,
            board_id=s.board_id,
            seq=s.seq,
            ranges_m=tuple(med),
            status=tuple("ok" if math.isfinite(r) else n for r, n in zip(med, names, strict=True)),  # type: ignore[misc]
            voltages_v=tuple(volts),
            raw_counts=tuple(int(c) for c in s.counts),
        )

    def _convert(self, s: RawSample, stamp_ns: int) -> IrScan:
        """The per-sample numpy path (counts the tables do not hold)."""
        cfg = self.config
        counts = np.asarray(s.counts, dtype=float)
        volts = counts * (cfg.vref_v / ((1 << cfg.adc_bits) - 1))
        if cfg.curves:
            ranges = np.empty(cfg.channels)
            status = np.empty(cfg.channels, dtype=np.int8)
            for i in range(cfg.channels):
                r, st = cfg.curve(i).range(volts[i : i + 1])
                ranges[i], status[i] = r[0], st[0]
        else:
            ranges, status = _DEFAULT_CURVE.range(volts)
        names = tuple(STATUS_NAMES[int(k)] for k in status)
        vv = tuple(float(v) for v in volts)
        if self._median is not None:
            return self._filtered(s, stamp_ns, ranges, vv, names)
        return IrScan(
            stamp_ns=stamp_ns,
            board_id=s.board_id,
            seq=s.seq,
            ranges_m=tuple(float(r) for r in ranges),
            status=names,  # type: ignore[arg-type]
            voltages_v=vv,
            raw_counts=tuple(int(c) for c in s.counts),
        )


@lru_cache(maxsize=16)
def _tables(
    adc_bits: int, vref_v: float, curves: tuple[SharpCurve, ...]
) -> tuple[dict, list, tuple[list, list, list] | None]:
    """count -> volts, per curve (count -> range, count -> status name), and with one curve
    the lists (volts, ranges, statuses) indexed by count, for every count of the resolution
    (one curve: the datasheet's on every channel)."""
    full = (1 << adc_bits) - 1
    volts = np.arange(full + 1, dtype=float) * (vref_v / full)
    out = []
    for curve in curves or (_DEFAULT_CURVE,):
        r, st = curve.range(volts)
        out.append(
            (dict(enumerate(float(x) for x in r)), dict(enumerate(STATUS_NAMES[k] for k in st)))
        )
    vt = dict(enumerate(float(v) for v in volts))
    lists = None
    if len(out) == 1:
        rt, st = out[0]
        lists = (list(vt.values()), list(rt.values()), list(st.values()))
    return vt, out, lists


def volts_to_counts(volts: np.ndarray, adc_bits: int, vref_v: float) -> np.ndarray:
    full = (1 << adc_bits) - 1
    return np.clip(np.round(np.asarray(volts) / vref_v * full), 0, full).astype(np.int64)
