"""A log's records in the order things happened, when its log time went back.

The log time of a record is when the daemon took it in, by the host's clock. If that
clock was set back while the log was recorded (msgs.stamps; the daemon's own stamps no
longer follow a step back, drivers.clock), log-time order interleaves the stretch before
the step with the one after it, and a replay would feed the filters a mix of two
stretches. The file holds the records in the order they were written, which is the order
they happened in, give or take a batch: the device loop writes a batch of reads up to a
tenth of a second late, and the services' outputs carry their input's time.

:func:`in_written_order` takes the records in file order and gives them back in log-time
order within each stretch: a heap holds them until the newest log time is a second past
theirs (``msgs.stamps.SET_BACK_NS``). A service input or raw bytes more than a second
older than the newest service input or raw bytes starts a new stretch, after the held
records are out, and is counted (``ReadStats.set_backs``). Only those records judge a
step: they are logged within a fraction of a second of their read, while an output
logged late with an old input's time is not a step. For a log whose time never went back
this is log-time order, except for records written more than a second late (service
outputs, which a replay replaces).
"""

from __future__ import annotations

import heapq
from collections.abc import Iterable, Iterator
from typing import TYPE_CHECKING

from hilnav.topics import RAW_PREFIX, SERVICE_INPUTS, split_log_topic
from msgs.stamps import SET_BACK_NS, set_back

if TYPE_CHECKING:
    from hilnav.log.reader import RawRecord, ReadStats


def judges(topic: str) -> bool:
    """Whether a record on this MCAP topic is logged as it was read (a service input or
    raw bytes), so that its log time going back is the host's clock going back."""
    name = split_log_topic(topic)[1]
    return name in SERVICE_INPUTS or name.startswith(RAW_PREFIX)


def in_written_order(
    records: Iterable[RawRecord], stats: ReadStats | None = None
) -> Iterator[RawRecord]:
    """The records (in file order) in log-time order within each stretch (module doc)."""
    heap: list[tuple[int, int, RawRecord]] = []
    newest: int | None = None  # the newest log time of any record
    newest_input: int | None = None  # the newest of the records that judge a step
    for k, r in enumerate(records):
        t = r.log_time_ns
        if judges(r.topic):
            if newest_input is not None and set_back(t, newest_input):
                while heap:
                    yield heapq.heappop(heap)[2]
                newest = newest_input = None
                if stats is not None:
                    stats.set_backs += 1
            newest_input = t if newest_input is None else max(newest_input, t)
        heapq.heappush(heap, (t, k, r))
        newest = t if newest is None else max(newest, t)
        while heap and heap[0][0] <= newest - SET_BACK_NS:
            yield heapq.heappop(heap)[2]
    while heap:
        yield heapq.heappop(heap)[2]
