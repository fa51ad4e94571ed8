"""Freed memory stays in the process (solvers.allocator): a large freed array stays resident,
for the next arrays to reuse, instead of going back to the kernel; the environment variable
turns it off (the control: there the memory goes back to the kernel at once)."""

import json
import os
import platform
import subprocess
import sys

import pytest

from solvers.allocator import ENV_VARIABLE, allocator_report, format_allocator

GLIBC = platform.libc_ver()[0] == "glibc"

#: resident memory (MiB) around a 256 MiB array: allocated and written, then freed
_PROBE = """
import json, resource
import numpy as np
import solvers
from solvers.allocator import allocator_report

def rss():
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * resource.getpagesize() / 2**20

n = 256 * 2**20 // 8
a = np.ones(n); held = rss()
del a; freed = rss()
print(json.dumps({"held": held, "freed": freed, "report": allocator_report()}))
"""


def _probe(**env: str) -> dict:
    out = subprocess.run(
        [sys.executable, "-c", _PROBE],
        env={**os.environ, **env},
        capture_output=True,
        text=True,
        check=True,
    )
    return json.loads(out.stdout)


@pytest.mark.skipif(
    not GLIBC, reason="the policy is glibc's mallopt; other C libraries keep theirs"
)
def test_freed_arrays_stay_in_the_process_and_the_variable_turns_it_off():
    kept = _probe()
    assert kept["report"] == {"keep_freed_memory": True, "why_not": None}
    # the 256 MiB stay resident after the free
    assert kept["held"] - kept["freed"] < 16.0, kept
    control = _probe(**{ENV_VARIABLE: "0"})
    assert control["report"] == {"keep_freed_memory": False, "why_not": f"{ENV_VARIABLE}=0"}
    # glibc's default: the block was mmap'd and goes back to the kernel on free
    assert control["held"] - control["freed"] > 200.0, control


def test_the_report_says_what_this_process_does():
    report = allocator_report()
    if GLIBC and ENV_VARIABLE not in os.environ:  # importing solvers turned it on here
        assert report == {"keep_freed_memory": True, "why_not": None}
        assert "freed memory kept" in format_allocator()
    else:
        assert not report["keep_freed_memory"] and report["why_not"] in format_allocator()
