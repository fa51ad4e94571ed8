"""Helpers of the benchmark tests: one run of a benchmark's mode per test module, and the files
every record writes."""

import json
from pathlib import Path

import pytest

from benchmarks.runner import run_named


def record_fixture(name: str, mode: str = "quick", **options):
    """A module-scoped fixture that runs benchmark ``name`` (a registered name or alias) in
    ``mode`` once: ``(summary, the record read back from its JSON, the output folder)``."""

    @pytest.fixture(scope="module")
    def result(tmp_path_factory):
        out = tmp_path_factory.mktemp(name)
        summary = run_named(name, mode, out, **options)
        return summary, json.loads(Path(summary["json"]).read_text()), out

    return result


def check_written(result, stem: str, keys: str = "", png_bytes: int = 10_000) -> dict:
    """The run wrote ``stem.json`` (the path it returned) and a plot of more than
    ``png_bytes`` bytes, and its record holds ``keys`` (space-separated); returns the record."""
    summary, data, out = result
    assert summary["json"] == str(out / f"{stem}.json")
    assert (out / f"{stem}.png").stat().st_size > png_bytes
    for key in keys.split():
        assert key in data, key
    return data
