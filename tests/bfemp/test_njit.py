"""``bfemp._njit.serial_or_parallel``: two builds of one loop, each with its own disk cache."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np

from bfemp._njit import compile_parallel_builds, serial_or_parallel

MODULE = """
from numba import prange
from bfemp._njit import serial_or_parallel

@serial_or_parallel(100)
def scale(a, out):
    for i in prange(a.shape[0]):
        out[i] = 2.0 * a[i]
"""


def test_the_parallel_build_never_loads_the_serial_builds_cache_entry(tmp_path: Path) -> None:
    """One process compiles and caches the serial build; a second process must compile the
    parallel build itself (a cache miss), not load the serial code from the shared cache (what
    happened when both builds were filed under one name: the parallel kernel ran serially)."""
    (tmp_path / "twin_mod.py").write_text(MODULE)
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    env["PYTHONPATH"] = os.pathsep.join([str(tmp_path), str(Path(__file__).resolve().parents[2])])
    probe = textwrap.dedent(
        """
        import sys, numpy as np, twin_mod
        build = getattr(twin_mod.scale, sys.argv[1])
        a = np.arange(5.0); out = np.empty(5)
        build(a, out)
        assert (out == 2 * a).all()
        print("hits", sum(build.stats.cache_hits.values()))
        """
    )
    run = [sys.executable, "-c", probe]
    first = subprocess.run([*run, "serial"], env=env, capture_output=True, text=True, check=True)
    second = subprocess.run([*run, "parallel"], env=env, capture_output=True, text=True, check=True)
    assert first.stdout.split() == ["hits", "0"]
    assert second.stdout.split() == ["hits", "0"], second.stdout
    third = subprocess.run([*run, "parallel"], env=env, capture_output=True, text=True, check=True)
    assert third.stdout.split() == ["hits", "1"]  # its own entry, once saved


def test_builds_agree_and_dispatch_by_size() -> None:
    @serial_or_parallel(10)
    def square(a: np.ndarray, out: np.ndarray) -> None:
        for i in range(a.shape[0]):
            out[i] = a[i] * a[i]

    for n in (3, 50):
        a = np.linspace(0.0, 1.0, n)
        out = np.empty(n)
        square(a, out)
        np.testing.assert_array_equal(out, a * a)
    assert square.parallel.targetoptions.get("parallel") and not square.serial.targetoptions.get(
        "parallel"
    )


def test_warmup_compiles_the_parallel_build_for_each_signature_the_serial_one_met() -> None:
    @serial_or_parallel(1000)
    def halve(a: np.ndarray, out: np.ndarray) -> None:
        for i in range(a.shape[0]):
            out[i] = 0.5 * a[i]

    a = np.arange(4.0)
    out = np.empty(4)
    halve(a, out)  # below the threshold: the serial build only
    assert halve.serial.signatures and not halve.parallel.signatures
    assert compile_parallel_builds([halve]) == 1
    assert halve.parallel.signatures == halve.serial.signatures
    assert compile_parallel_builds([halve]) == 0  # nothing left to compile
