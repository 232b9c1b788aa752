"""The usual sentences of a receiver with a fix, each read and merged in one step.

:meth:`EpochCombiner.add_into` is the reference: it runs a sentence through
:meth:`Session.parse` (the handler fills a dict of new data, gpsd's ``newdata``) and
:meth:`Session.apply` (:func:`~drivers.nmea.fixstate.merge` copies it into the fix), with
the epoch bookkeeping around them. For the common case of the common types (GSA, VTG,
GST, ZDA here; GGA and RMC in :mod:`drivers.nmea.fastfix`, with the table of them all,
``FAST``) the readers do the same in one pass: they read the fields into
locals and write the fix directly, comparing each value with the fix's as ``merge`` does,
so the error model runs exactly when it would. Each function first checks that the
sentence is the ordinary case it covers (every field it needs present and well formed, no
GGA repeating its time, ...); when it is not, the sentence takes the reference path
before any state has changed (:func:`reference`). What is read and how is shared with the
reference (:mod:`drivers.nmea.fields`, the session's and the combiner's methods, the
error model); tests/test_nmea_fastpath.py checks both paths give the same messages, stats
and session state on gpsd's logs, damaged copies of them and synthetic streams.

Signature: ``f(rest, stamp_ns, out, combiner, talker)``, ``rest`` the text of the fields
after the address (between the first comma and the ``*``); a route is such a function
with the combiner and the talker bound (:func:`bind`).

The error model runs after a sentence that changed the fix or the DOPs (or left a track
outside 0-360 degrees). After every sentence, on either path, the DOPs equal those the
error model last saw (it runs when they differ), so a sentence that does not touch the
DOPs (VTG, GST, ZDA) need not compare them.
"""

from __future__ import annotations

from collections.abc import Callable
from types import FunctionType
from typing import TYPE_CHECKING

from drivers.nmea.errmodel import error_model, motion_model
from drivers.nmea.fields import NUMBERS as nums
from drivers.nmea.fields import clock, ddmmyy, read_number
from drivers.nmea.fixstate import MODE_3D, MODE_NO_FIX, MODE_SET
from drivers.nmea.handlers import KNOTS_TO_MPS
from drivers.nmea.memo import table
from drivers.nmea.session import DAY_NS, ROLLOVER_S, days_from_civil
from drivers.nmea.sky import _gsa_fields, _gsv_fields

if TYPE_CHECKING:
    from drivers.nmea.epoch import EpochCombiner

HOUR_NS = 3_600_000_000_000
_NONE: dict = {}  # the new data the error model sees: none of the estimates it keeps
_CACHE_MAX = 64
_TIMES: dict[str, tuple[int | None, float | None]] = table({})
_DATES: dict[str, tuple] = table({})
# a GST's and a ZDA's fields after the time -> what they say (_gst_stats, _zda_date)
_GST: dict[str, tuple] = table({})
_ZDA: dict[str, tuple] = table({})
# (talker, a GSA's fields text) -> what it says (sky._gsa_fields; () when too short)
_GSA: dict[tuple[str, str], tuple] = table({})
# (talker, a GSV's fields text) -> what it says (sky._gsv_fields)
_GSV: dict[tuple[str, str], tuple] = table({})


def _time(s: str) -> tuple[int | None, float | None]:
    """(time of day in ns, the field as a number): what the cycle detector registers
    (readers look in ``_TIMES`` first: ``_TIMES.get(s) or _time(s)``)."""
    if len(_TIMES) >= _CACHE_MAX:
        _TIMES.clear()
    t = _TIMES[s] = clock(s)
    return t


def _date(s: str) -> tuple:
    """((year, month, day), days since 1970) of an RMC date, () if it is none."""
    d = _DATES.get(s)
    if d is None:
        if len(_DATES) >= _CACHE_MAX:
            _DATES.clear()
        ymd = ddmmyy(s)
        d = _DATES[s] = () if ymd is None else (ymd, days_from_civil(*ymd))
    return d


def reference(
    rest: str, stamp: int, out: list, comb: EpochCombiner, talker: str, kind: str
) -> None:
    """A sentence (its type ``kind``, its fields' text ``rest``) the reference way."""
    comb.add_into(talker, kind, tuple(rest.split(",")), stamp, out)


def bind(reader: Callable[..., None], *given: object) -> Callable[[str, int, list], None]:
    """``reader`` with its arguments after ``(rest, stamp, out)`` given: a copy of the
    function with them as its defaults (a call costs what a plain call does; a
    functools.partial adds about half of that)."""
    return FunctionType(reader.__code__, reader.__globals__, reader.__name__, given)


def gsa(rest: str, stamp: int, out: list, comb: EpochCombiner, talker: str) -> None:
    st = comb.session
    key = (talker, rest)
    read = _GSA.get(key)
    if read is None:
        f = tuple(rest.split(","))
        read = _gsa_fields(talker, f) if len(f) >= 17 else ()
        if len(_GSA) >= _CACHE_MAX:
            _GSA.clear()
        _GSA[key] = read
    if not read:
        return _short_gsa(stamp, comb)
    if st.latch_mode:
        return reference(rest, stamp, out, comb, talker, "GSA")
    # --- the ordinary GSA from here on (Session.parse, Sky.gsa)
    st.latch_frac = st.gsx_more = False
    sky = st.sky
    mask = sky.gsa_read(talker, read)
    sky.last_gsv_talker = ""
    fix = st.fix
    changed = False
    if mask & MODE_SET:  # (it is all of GSA's that makes an epoch worth a fix)
        mode = read[0]
        if mode != MODE_NO_FIX and mode != MODE_3D and fix.mode == MODE_3D and st._had_altitude():
            mode = MODE_3D
        comb._pending = True
        comb._snap = None
        if fix.mode != mode:
            fix.mode = mode
            changed = True
    elif comb._pending and comb._snap is None:  # (the new data: the mode)
        comb._snap = fix.copy()
    if changed or sky.dop != st._dops or st._unnormed:
        error_model(st, _NONE)
    comb._stamp_ns = stamp


def _short_gsa(stamp: int, comb: EpochCombiner) -> None:
    """A GSA of fewer fields than gpsd reads (an old receiver's without a fix: Garmin's
    ``$GPGSA,A,1,,,,,,,,,,,,,,,``): counted malformed and read no further, as the
    reference path does (Session.parse and apply with no data)."""
    st = comb.session
    st.malformed += 1
    st.latch_frac = st.gsx_more = False
    st.sky.last_gsv_talker = ""
    if st.sky.dop != st._dops or st._unnormed:
        error_model(st, _NONE)
    comb._stamp_ns = stamp


def gsv(rest: str, stamp: int, out: list, comb: EpochCombiner, talker: str) -> None:
    """Every GSV (Session.parse and apply, Sky.gsv, EpochCombiner.add_into): a GSV sets
    no fix data; a complete set computes the DOPs the receiver did not give."""
    key = (talker, rest)
    read = _GSV.get(key)
    if read is None:
        read = _gsv_fields(talker, rest.split(","))
        if len(_GSV) >= _CACHE_MAX:
            _GSV.clear()
        _GSV[key] = read
    st = comb.session
    st.latch_frac = False
    sky = st.sky
    mask, st.gsx_more = sky.gsv_read(talker, read)
    sky.last_gsa_talker = ""
    if mask:  # (SATELLITE_SET: the fix as last reported is kept for the report)
        if comb._pending and comb._snap is None:
            comb._snap = st.fix.copy()
        if sky.view:
            sky.fill_dop()
    if sky.dop != st._dops or st._unnormed:
        error_model(st, _NONE)
    comb._stamp_ns = stamp


def vtg(rest: str, stamp: int, out: list, comb: EpochCombiner, talker: str) -> None:
    f = rest.split(",")
    if len(f) < 9:
        return reference(rest, stamp, out, comb, talker, "VTG")
    f0, f4 = f[0], f[4]
    if not f0 or not f4 or f[8][:1] in ("E", "N"):
        return reference(rest, stamp, out, comb, talker, "VTG")
    st = comb.session
    st.latch_frac = st.gsx_more = False
    sky = st.sky
    sky.last_gsv_talker = sky.last_gsa_talker = ""
    track = nums.get(f0) or read_number(f0)
    magtrack = (nums.get(f[2]) or read_number(f[2])) if f[2] else None
    speed = nums.get(f4) or read_number(f4)
    if speed is not None:
        speed *= KNOTS_TO_MPS
    comb._pending = True
    comb._snap = None
    fix = st.fix
    changed = False
    if fix.track != track:
        fix.track = track
        changed = True
    if magtrack is not None and fix.magtrack != magtrack:
        fix.magtrack = magtrack
        changed = True
    if fix.speed != speed:
        fix.speed = speed
        changed = True
    if st._unnormed or (
        changed
        and (
            speed is None or fix.vel_n is not None or fix.vel_e is not None or fix.vel_d is not None
        )
    ):
        error_model(st, _NONE)
    elif changed:  # (the speed and tracks alone: errmodel.motion_model's conditions hold)
        motion_model(st)
    comb._stamp_ns = stamp
    comb._talker = talker


def gst(rest: str, stamp: int, out: list, comb: EpochCombiner, talker: str) -> None:
    f0, _, tail = rest.partition(",")
    stats = _GST.get(tail)
    if stats is None:
        stats = _gst_stats(tail)
    if not stats:
        return reference(rest, stamp, out, comb, talker, "GST")
    st = comb.session
    st.latch_frac = st.gsx_more = False
    sky = st.sky
    sky.last_gsv_talker = sky.last_gsa_talker = ""
    st.gst = stats
    st.gst_tod = (_TIMES.get(f0) or _time(f0))[0]
    if st._unnormed:
        error_model(st, _NONE)
    comb._stamp_ns = stamp
    comb._talker = talker


def _gst_stats(tail: str) -> tuple:
    """The 7 numbers of a GST after its time (handlers.gst), () if it has fewer."""
    f = tail.split(",")
    if len(f) >= 7:
        a, b, c, d, e, g, h = f[:7]
        get = nums.get  # (number(), the empty fields and the table looked at first)
        stats = ((get(a) or read_number(a)) if a else None, (get(b) or read_number(b)) if b else None,
                 (get(c) or read_number(c)) if c else None, (get(d) or read_number(d)) if d else None,
                 (get(e) or read_number(e)) if e else None, (get(g) or read_number(g)) if g else None,
                 (get(h) or read_number(h)) if h else None)  # fmt: skip
    else:
        stats = ()
    if len(_GST) >= _CACHE_MAX:
        _GST.clear()
    _GST[tail] = stats
    return stats


def zda(rest: str, stamp: int, out: list, comb: EpochCombiner, talker: str) -> None:
    f0, _, tail = rest.partition(",")
    date = _ZDA.get(tail)
    if date is None:
        date = _zda_date(tail)
    ns = (_TIMES.get(f0) or _time(f0))[0]
    if not date or ns is None:
        return reference(rest, stamp, out, comb, talker, "ZDA")
    # --- the ordinary ZDA from here on (Session.parse, handlers.zda, Session.set_date)
    ymd, day = date
    st = comb.session
    st.latch_frac = st.gsx_more = False
    st.tod_ns = ns  # (a midnight wrap of the day is overridden by the date just below)
    st.date = ymd
    if st.rollover_before_year is not None and ymd[0] < st.rollover_before_year:
        day += ROLLOVER_S // 86400
    st.day = day
    sky = st.sky
    sky.last_gsv_talker = sky.last_gsa_talker = ""
    time_ns = day * DAY_NS + ns
    comb._pending = True
    comb._snap = None
    fix = st.fix
    changed = False
    if not time_ns and st.lastfix is fix:
        st.lastfix = fix.copy()
    if fix.time_ns != time_ns:
        fix.time_ns = time_ns
        changed = True
    if changed or st._unnormed:
        error_model(st, _NONE)
    comb._stamp_ns = stamp
    comb._talker = talker
    comb.timed("ZDA", out)


def _zda_date(tail: str) -> tuple:
    """((year, month, day), days since 1970) of a ZDA after its time, () unless the
    fields are the ordinary ones (day, month, four-digit year in gpsd's bounds)."""
    f = tail.split(",")
    date: tuple = ()
    if len(f) >= 3:
        f1, f2, f3 = f[0], f[1], f[2]
        if f1.isdigit() and f2.isdigit() and f3.isdigit() and len(f3) == 4:
            y, m, d = int(f3), int(f2), int(f1)
            if 1900 <= y <= 2200 and 1 <= m <= 12 and 1 <= d <= 31:
                date = ((y, m, d), days_from_civil(y, m, d))
    if len(_ZDA) >= _CACHE_MAX:
        _ZDA.clear()
    _ZDA[tail] = date
    return date
