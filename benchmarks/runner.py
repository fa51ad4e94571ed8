"""The benchmark catalogue: one ``Benchmark`` entry per experiment and one runner.

A benchmark module builds its entry and registers it::

    BENCHMARK = register(Benchmark(NAME, "title", MODES, measure, plot=_plot))
    run = BENCHMARK.run  # run(mode, out, **options) -> {"json": path, "png": path, ...}

``measure(mode, cfg, **options)`` returns the record's payload (``cfg`` is ``modes[mode]``;
``options`` from the command line where the entry declares ``arguments``); the
runner (``Benchmark.run``) checks the mode, records the environment before the measurement and
the peak memory after it, adds ``benchmark``, ``mode`` and ``wall_s`` where the payload has none,
writes ``out/STEM.json`` (``STEM`` from ``record(mode)``), the optional ``.md`` report and the
optional plot. ``python -m benchmarks NAME`` finds every registered entry (``catalogue()``), and
``python -m benchmarks verify NAME ...`` reruns quick modes against the committed records
(``verify``).
"""

from __future__ import annotations

import argparse
import importlib
import json
import math
import pkgutil
import re
import tempfile
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

from benchmarks.common import environment, peak_memory_mb, write_json

#: name -> entry, filled by ``register`` as the modules are imported (``catalogue()``)
REGISTRY: dict[str, Benchmark] = {}
#: modules of the package that hold no benchmark
_NOT_BENCHMARKS = {"__main__", "cli", "common", "runner", "catalogue"}
RECORDS = Path(__file__).resolve().parent / "records"


def name_unless(default: str, name: str) -> Callable[[str, Mapping], str]:
    """Record stem: ``name`` in mode ``default``, ``name_MODE`` in the others."""
    return lambda mode, options: name if mode == default else f"{name}_{mode}"


@dataclass(frozen=True)
class Benchmark:
    """One experiment of the catalogue.

    Attributes:
        name: the command-line name (``python -m benchmarks NAME``).
        title: one line: what is measured (a docstring given is cut to its first line).
        modes: mode -> its parameters (passed to ``measure`` as ``cfg``).
        measure: ``measure(mode, cfg, **options) -> payload`` (a JSON-ready dict).
        plot: ``plot(payload, png_path)``, or None for a record without a figure.
        report: ``report(payload) -> str``: Markdown written beside the JSON, or None.
        record: ``record(mode, options) -> stem`` of the files written (default: the name).
        timings: a regular expression of the record's keys that hold times or ratios of times
            (beside ``TIMING_KEY``), left out by ``verify``: e.g. ``"_s$"`` for a timing
            benchmark whose every ``*_s`` is a measured time.
        aliases: other names that run this entry (old names of merged benchmarks), each with
            the options it implies: ``{alias: {option: value}}``.
        arguments: ``arguments(group)`` adds the benchmark's own command-line options to an
            argparse group; ``python -m benchmarks NAME`` passes their values to ``measure``.
        needs_out: ``measure`` also takes ``out=Path(out)``, the output folder, for a benchmark
            that keeps files beside its record (finished cases to resume a stopped run,
            checkpoints, child processes' records).
    """

    name: str
    title: str
    modes: Mapping[str, Mapping]
    measure: Callable[..., dict]
    plot: Callable[[dict, Path], None] | None = None
    report: Callable[[dict], str] | None = None
    record: Callable[[str, Mapping], str] | None = None
    timings: str = ""
    aliases: Mapping[str, Mapping] = field(default_factory=dict)
    arguments: Callable[[argparse._ActionsContainer], None] | None = None
    needs_out: bool = False

    def __post_init__(self) -> None:
        object.__setattr__(self, "title", self.title.strip().split("\n")[0])

    @property
    def module(self) -> str:
        """The module that defines the benchmark."""
        return self.measure.__module__

    def stem(self, mode: str, options: Mapping | None = None) -> str:
        """The file stem of the record of ``mode`` run with ``options``."""
        return self.name if self.record is None else self.record(mode, options or {})

    def check_mode(self, mode: str) -> Mapping:
        """The parameters of ``mode``; a ValueError naming the modes otherwise."""
        if mode not in self.modes:
            raise ValueError(f"mode must be one of {sorted(self.modes)}, got {mode!r}")
        return self.modes[mode]

    def run(self, mode: str = "full", out: str | Path = "results", **options) -> dict:
        """Measure ``mode`` and write its record to ``out``; returns ``{"json": path, "png":
        path (with a plot), "md": path (with a report), **record}``. Keys of the measured
        payload that start with an underscore (per-step series, snapshots) reach the plot and
        the report but not the record."""
        cfg = self.check_mode(mode)
        env = environment()  # before the run: the commit that ran, not the one at the end
        started = time.perf_counter()
        where = {"out": Path(out)} if self.needs_out else {}
        measured = self.measure(mode, cfg, **options, **where)
        wall = time.perf_counter() - started
        payload = {"benchmark": self.name, "mode": mode, **measured}
        payload.setdefault("wall_s", wall)
        payload.setdefault("peak_memory_mb", peak_memory_mb())
        payload.setdefault("environment", env)
        return write_record(out, self.stem(mode, options), payload, self.plot, self.report)


def write_record(
    out: str | Path,
    stem: str,
    payload: dict,
    plot: Callable[[dict, Path], None] | None = None,
    report: Callable[[dict], str] | None = None,
) -> dict:
    """Write ``out/STEM.json`` (the payload without its underscored keys, with the peak memory
    and the environment where it has none), ``STEM.md`` from ``report(payload)`` and
    ``STEM.png`` from ``plot(payload, path)``; returns ``{"json": path, "png": path, "md":
    path, **record}`` (the files written)."""
    payload.setdefault("peak_memory_mb", peak_memory_mb())
    payload.setdefault("environment", environment())
    out = Path(out)
    record = {k: v for k, v in payload.items() if not k.startswith("_")}
    summary = {"json": str(write_json(out, stem, record))}
    if report is not None:
        md = out / f"{stem}.md"
        md.write_text(report(payload))
        summary["md"] = str(md)
    if plot is not None:
        png = out / f"{stem}.png"
        plot(payload, png)
        if png.exists():  # a plot may have nothing to draw for some options
            summary["png"] = str(png)
    return {**summary, **record}


def mode_options(parser: argparse.ArgumentParser) -> None:
    """``--quick``, ``--full``, ``--mode M`` (one of them; ``args.mode`` None: full) and
    ``--out DIR``: the options of every benchmark's command line."""
    mode = parser.add_mutually_exclusive_group()
    mode.add_argument("--quick", action="store_const", const="quick", dest="mode")
    mode.add_argument("--full", action="store_const", const="full", dest="mode")
    mode.add_argument(
        "--mode",
        dest="mode",
        help="another mode of the benchmark (rings: partial; hertz: refined; "
        "buckling: partial, plate_quick, plate_partial, plate_full; "
        "twist: partial, partial_probe, full_probe)",
    )
    parser.add_argument("--out", default="results", help="output folder (default results/)")


def register(benchmark: Benchmark) -> Benchmark:
    """Add ``benchmark`` to the catalogue (a name already taken is an error); returns it."""
    for name in (benchmark.name, *benchmark.aliases):
        other = REGISTRY.get(name)
        if other is not None and other is not benchmark:
            raise ValueError(f"benchmark name {name!r} registered twice")
        REGISTRY[name] = benchmark
    return benchmark


def catalogue() -> dict[str, Benchmark]:
    """Every registered benchmark by name (aliases included), importing the package's
    modules."""
    package = Path(__file__).resolve().parent
    for info in pkgutil.iter_modules([str(package)]):
        if not info.name.startswith("_") and info.name not in _NOT_BENCHMARKS:
            importlib.import_module(f"benchmarks.{info.name}")
    return dict(REGISTRY)


def run_named(name: str, mode: str, out: str | Path, module: object = None, **options) -> dict:
    """Run the benchmark (or alias) ``name``: an alias adds the options it stands for. A
    ``module`` given (``bfemp bench``'s plug-ins) runs through its ``run(mode, out)``."""
    bench = catalogue().get(name)
    if bench is None and module is None:
        raise ValueError(f"unknown benchmark {name!r}; available: {', '.join(sorted(REGISTRY))}")
    if bench is None or bench.module != getattr(module, "__name__", bench.module):
        return module.run(mode, out, **options)
    return bench.run(mode, out, **{**bench.aliases.get(name, {}), **options})


# --------------------------------------------------------------------------- verify
#: keys whose values are measured times, machine load or memory, or provenance (the commit a
#: point ran on, the command that replays it from its record's folder): not compared by ``verify``
TIMING_KEY = re.compile(
    r"(^|_)(wall|cpu|timings?|elapsed|seconds|per_s|speedup|phases?)(_|$)|^time_|_time_s$|"
    r"s_per_step|time_per_step|_per_query$|"
    r"^(environment|peak_memory_mb|merged_from|load_average_1min|segments_s|commit|replay)$"
)


def differences(old: object, new: object, path: str = "", timings: str = "") -> list[str]:
    """Where two records differ outside timing fields (``TIMING_KEY`` and the regular
    expression ``timings``); floats compared exactly (bit for bit, NaN equal to NaN)."""
    if isinstance(old, dict) and isinstance(new, dict):
        out = []
        for key in sorted(set(old) | set(new), key=str):
            if TIMING_KEY.search(str(key)) or (timings and re.search(timings, str(key))):
                continue
            if key not in old or key not in new:
                out.append(f"{path}/{key}: only in the {'new' if key in new else 'old'} record")
            else:
                out += differences(old[key], new[key], f"{path}/{key}", timings)
        return out
    if isinstance(old, list) and isinstance(new, list):
        if len(old) != len(new):
            return [f"{path}: {len(old)} items, now {len(new)}"]
        return [
            d
            for k, (a, b) in enumerate(zip(old, new, strict=True))
            for d in differences(a, b, f"{path}[{k}]", timings)
        ]
    both_nan = (
        isinstance(old, float) and isinstance(new, float) and math.isnan(old) and math.isnan(new)
    )
    return [] if old == new or both_nan else [f"{path}: {old!r}, now {new!r}"]


def verify(name: str, mode: str = "quick", records: Path = RECORDS) -> list[str]:
    """Rerun ``mode`` of ``name`` into a temporary folder and return the differences of its
    non-timing fields from the committed record ``records/STEM.json`` (empty: reproduced)."""
    bench = catalogue().get(name)
    if bench is None:
        raise ValueError(f"unknown benchmark {name!r}; available: {', '.join(sorted(REGISTRY))}")
    options = bench.aliases.get(name, {})
    committed = records / f"{bench.stem(mode, options)}.json"
    if not committed.exists():
        raise ValueError(f"{name}: no committed record {committed}")
    recorded = json.loads(committed.read_text()).get("mode", mode)
    if recorded != mode:  # e.g. hertz.json is the full run: every field would differ
        raise ValueError(f"{name}: the committed {committed.name} is a {recorded} run, not {mode}")
    with tempfile.TemporaryDirectory() as tmp:
        summary = bench.run(mode, tmp, **options)
        new = json.loads(Path(summary["json"]).read_text())
    return differences(json.loads(committed.read_text()), new, timings=bench.timings)
