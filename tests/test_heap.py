"""hilnav.heap: glibc's heap slack is set where it can be, and left alone where the
environment sets it or the C library is another."""

from __future__ import annotations

import os
import subprocess
import sys

from hilnav import heap


def test_the_environment_rules_and_other_libraries_are_left_alone(monkeypatch):
    monkeypatch.setenv("MALLOC_TOP_PAD_", "0")
    assert heap.keep_heap_slack() is False
    monkeypatch.delenv("MALLOC_TOP_PAD_")
    monkeypatch.setattr(heap.sys, "platform", "darwin")
    assert heap.keep_heap_slack() is False


def test_glibc_takes_it_in_a_fresh_process():
    env = {k: v for k, v in os.environ.items() if not k.startswith("MALLOC_")}
    code = "from hilnav.heap import keep_heap_slack; print(keep_heap_slack())"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         env=env, check=True).stdout.strip()  # fmt: skip
    glibc = sys.platform == "linux" and bool(os.confstr("CS_GNU_LIBC_VERSION"))
    assert out == str(glibc)
