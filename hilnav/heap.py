"""The process's heap: slack kept at its top for numpy's short-lived arrays (glibc only).

Mapping with data association makes and frees arrays of 0.1-1 MB for every IR scan
(the lattice points and cells of the beams' cones, for the map, the reference map and
the four drift hypotheses' maps). glibc's malloc gives the free memory at the top of
the heap back to the kernel once it exceeds its trim threshold, and the next scan takes
it again page by page, each page a minor fault in the kernel: a replay of the demo's
80 s log faulted 350,000 times and spent about 1 s of its 13 s of CPU in the kernel.
``M_TOP_PAD`` keeps that much slack at the top of the heap when it shrinks and asks for
that much more when it grows (pages are resident only once touched), which leaves
glibc's own adaptive thresholds as they are. The daemon's RSS may stay up to that much
above its needs after a peak. A ``MALLOC_TOP_PAD_`` in the environment (glibc's own
setting) is left to rule; other C libraries are left alone.
"""

from __future__ import annotations

import os
import sys

M_TOP_PAD = -2  # glibc's malloc.h
TOP_PAD_BYTES = 32 << 20


def keep_heap_slack(nbytes: int = TOP_PAD_BYTES) -> bool:
    """Ask glibc's malloc to keep ``nbytes`` of slack at the top of the heap; True if it
    was set (False: not glibc, or the environment sets it)."""
    if sys.platform != "linux" or "MALLOC_TOP_PAD_" in os.environ:
        return False
    try:
        if not os.confstr("CS_GNU_LIBC_VERSION"):
            return False
        import ctypes

        return bool(ctypes.CDLL("libc.so.6").mallopt(M_TOP_PAD, int(nbytes)))
    except (OSError, ValueError, AttributeError):
        return False
