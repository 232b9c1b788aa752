"""The process's heap: slack kept at its top for numpy's short-lived arrays (glibc only).

Mapping with data association makes and frees arrays of 0.1-1 MB for every IR scan
(the lattice points and cells of the beams' cones, for the map, the reference map and
the four drift hypotheses' maps). glibc's malloc gives the free memory at the top of
the heap back to the kernel once it exceeds its trim threshold, and the next scan takes
it again page by page, each page a minor fault in the kernel: a replay of the demo's
80 s log faulted 350,000 times and spent about 1 s of its 13 s of CPU in the kernel.

``M_TOP_PAD`` keeps 32 MiB of slack at the top of the heap when it shrinks (pages are
resident only once touched). Setting any of glibc's thresholds turns its adaptive mmap
threshold off (every array above 128 KiB would then be mapped and unmapped each time),
so ``M_MMAP_THRESHOLD`` is set too: arrays below 4 MiB come from the heap, larger ones
(a map copy) are mapped. Measured on the demo's association: 245,000 faults -> 27,000,
CPU -10-20 %; the daemon's RSS may stay up to the slack above its needs after a peak.
``MALLOC_TOP_PAD_`` or ``MALLOC_MMAP_THRESHOLD_`` in the environment (glibc's own
settings) are left to rule; other C libraries are left alone.
"""

from __future__ import annotations

import os
import sys

M_TOP_PAD = -2  # glibc's malloc.h
M_MMAP_THRESHOLD = -3
TOP_PAD_BYTES = 32 << 20
MMAP_THRESHOLD_BYTES = 4 << 20


def keep_heap_slack(
    top_pad: int = TOP_PAD_BYTES, mmap_threshold: int = MMAP_THRESHOLD_BYTES
) -> bool:
    """Ask glibc's malloc to keep ``top_pad`` bytes of slack at the top of the heap and
    to map only arrays of ``mmap_threshold`` bytes or more; True if it was set (False:
    not glibc, or the environment sets either)."""
    if sys.platform != "linux" or any(
        k in os.environ for k in ("MALLOC_TOP_PAD_", "MALLOC_MMAP_THRESHOLD_")
    ):
        return False
    try:
        if not os.confstr("CS_GNU_LIBC_VERSION"):
            return False
        import ctypes

        libc = ctypes.CDLL("libc.so.6")
        return bool(libc.mallopt(M_MMAP_THRESHOLD, int(mmap_threshold))) and bool(
            libc.mallopt(M_TOP_PAD, int(top_pad))
        )
    except (OSError, ValueError, AttributeError):
        return False
