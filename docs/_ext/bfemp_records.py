"""Sphinx extension: documentation pages generated from the repository at build time.

On ``builder-inited`` it writes Markdown pages into ``docs/generated/`` (not committed):

- ``strategy_table.md``: ``bfemp.strategy_table()`` (the capabilities each strategy declares in
  code) and the conformance summary, ``benchmarks.conformance.readme_table`` of
  ``benchmarks/records/conformance.json`` (the same table the README holds);
- ``reproductions/NAME.md``: one page per benchmark with records in ``benchmarks/records/``:
  the benchmark module's docstring, then per record file its targets against the measured
  values, the paper's figures, the top-level results, tables of its per-case rows, its plot
  (copied beside the page) and the markdown report the benchmark wrote, if any;
- ``tradeoff.md`` (+ ``tradeoff_report_MODE.md``): the trade study's winners per error range,
  non-dominated fronts and plots per scene, from ``records/tradeoff*.json``.

Every number on these pages is read from a record when the site is built: rerunning a
benchmark and committing its record changes the page, nothing is copied by hand. Files are
rewritten only when their text changes, so an incremental build rereads only what moved.
"""

from __future__ import annotations

import importlib
import json
import math
import shutil
from pathlib import Path

#: benchmark families in the order of the reproductions index, each with the paper (or the
#: purpose) it reproduces; a benchmark with records that is in no family lands in "other"
FAMILIES: tuple[tuple[str, str, tuple[str, ...]], ...] = (
    (
        "BFEMP paper (barrier MPM-FEM coupling)",
        "The paper's experiments under `barrier`.",
        ("rings", "slope", "hertz", "sine_boundary", "refinement", "buckling", "twist"),
    ),
    (
        "Augury contact (AUG)",
        "The augury paper's experiments under `augury`.",
        ("augury_gap", "augury_blocks", "augury_ramp", "augury_probes", "augury_scenes"),
    ),
    (
        "Two-stage (explicit elasticity, implicit contact)",
        "The `two_stage` strategy on the BFEMP scenes and the augury gap.",
        ("two_stage_slope", "two_stage_rings", "two_stage_gap"),
    ),
    (
        "Logistic-regression contact (LR)",
        "The LR paper's experiments under `lr`.",
        ("lr_compression", "lr_contact_time", "lr_ellipses", "lr_scenes", "lr_variants"),
    ),
    (
        "Robustness and conformance",
        "Every strategy against its declared guarantees, at the extremes and on random scenes.",
        ("conformance", "extremes", "fuzz", "ccd_oracle"),
    ),
    (
        "Performance",
        "Wall times of the solvers and engines.",
        (
            "perf_fem",
            "perf_mpm",
            "perf_3d",
            "perf_contact",
            "perf_explicit",
            "perf_threads",
            "perf_broadphase",
            "blas_wall",
            "speed_knobs",
        ),
    ),
)

#: top-level keys that are bookkeeping, not results
_SKIP = {"benchmark", "mode", "environment", "targets", "paper", "parameters", "points"}
_MAX_ROWS = 40
_MAX_COLS = 12


def fmt(value: object) -> str:
    """A value as a table cell: floats to 4 significant digits, None as '-', lists shortened."""
    if value is None:
        return "-"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return f"{value:.4g}"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, list | tuple):
        if len(value) <= 4 and all(not isinstance(v, dict | list) for v in value):
            return "[" + ", ".join(fmt(v) for v in value) + "]"
        return f"({len(value)} values)"
    if isinstance(value, dict):
        if _small_dict(value):
            return ", ".join(f"{k} {fmt(v)}" for k, v in value.items())
        return f"({len(value)} entries)"
    text = str(value).replace("|", "\\|").replace("\n", " ")
    return text


def _small_dict(value: dict) -> bool:
    """A dict shown in one cell: at most 4 entries, none of them a container."""
    return len(value) <= 4 and all(
        v is None or isinstance(v, bool | int | float | str) for v in value.values()
    )


def _scalar(value: object) -> bool:
    """Whether ``value`` fits one table cell."""
    if value is None or isinstance(value, bool | int | float | str):
        return True
    if isinstance(value, list):
        return len(value) <= 4 and all(_scalar(v) for v in value)
    return isinstance(value, dict) and _small_dict(value)


def table(header: list[str], rows: list[list[object]]) -> list[str]:
    """A Markdown table (cells through :func:`fmt`)."""
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(fmt(c) for c in row) + " |" for row in rows]
    return lines + [""]


def _key_table(mapping: dict, what: str = "value") -> list[str]:
    rows = [[f"`{k}`", v] for k, v in mapping.items() if _scalar(v)]
    return table(["quantity", what], rows) if rows else []


def _rows_table(rows: list[dict]) -> list[str]:
    """Per-case rows (a list of dicts): their scalar columns, first ``_MAX_COLS``."""
    cols: list[str] = []
    for row in rows[:_MAX_ROWS]:
        cols += [k for k, v in row.items() if _scalar(v) and k not in cols]
    cols = cols[:_MAX_COLS]
    lines = table(cols, [[r.get(c) for c in cols] for r in rows[:_MAX_ROWS]])
    if len(rows) > _MAX_ROWS:
        lines.insert(-1, f"\n({len(rows) - _MAX_ROWS} more rows in the record)")
    return lines


def _docstring(module: str) -> str | None:
    try:
        mod = importlib.import_module(f"benchmarks.{module}")
    except Exception:  # noqa: BLE001 - a benchmark that fails to import still gets its records
        return None
    return mod.__doc__


def _mode_of(path: Path, payload: dict) -> str:
    mode = payload.get("mode")
    return str(mode) if mode else path.stem


def record_section(path: Path, payload: dict, images: Path, rel: str, level: str) -> list[str]:
    """The Markdown of one record file (``images``: where its plot is copied; ``rel``: the
    page's path to that folder)."""
    records = path.parent
    name = path.relative_to(records.parent.parent).as_posix()
    lines = [f"{level} `{path.name}` ({_mode_of(path, payload)})", ""]
    commit = (payload.get("environment") or {}).get("commit")
    lines += [f"Record `{name}`" + (f", commit `{commit[:10]}`." if commit else "."), ""]
    targets = payload.get("targets")
    if isinstance(targets, dict):
        rows = [[f"`{k}`", t, payload.get(k, "see below")] for k, t in targets.items()]
        lines += ["Targets and what was measured:", ""] + table(
            ["quantity", "target", "measured"], rows
        )
    if isinstance(payload.get("paper"), dict):
        lines += ["The paper's figures:", ""] + _key_table(payload["paper"], "paper")
    results = {k: v for k, v in payload.items() if k not in _SKIP}
    scalars = {k: v for k, v in results.items() if _scalar(v)}
    if scalars:
        lines += ["Results:", ""] + _key_table(scalars)
    for key, value in results.items():
        if isinstance(value, list) and value and all(isinstance(r, dict) for r in value):
            lines += [f"`{key}`:", ""] + _rows_table(value)
        elif isinstance(value, dict) and value and all(isinstance(v, dict) for v in value.values()):
            sub = [{"": k, **v} for k, v in value.items()]
            lines += [f"`{key}`:", ""] + _rows_table(sub)
        elif isinstance(value, dict) and not _scalar(value) and any(map(_scalar, value.values())):
            lines += [f"`{key}`:", ""] + _key_table(value)
    if isinstance(payload.get("parameters"), dict):
        lines += ["Parameters:", ""] + _key_table(payload["parameters"])
    png = path.with_suffix(".png")
    if png.exists():
        target = images / f"{path.parent.name}_{png.name}"
        _copy(png, target)
        lines += [f"![{png.name}]({rel}/{target.name})", ""]
    report = path.with_suffix(".md")
    if report.exists():
        lines += [
            f"The report the benchmark wrote (`{report.name}`):",
            "",
            "```{include} " + _include_path(report, images.parent),
            ":heading-offset: 2",
            "```",
            "",
        ]
    return lines


def _include_path(target: Path, page_dir: Path) -> str:
    return Path(_relpath(target, page_dir)).as_posix()


def _relpath(target: Path, start: Path) -> str:
    import os

    return os.path.relpath(target, start)


def _copy(src: Path, dst: Path) -> None:
    if not dst.exists() or dst.read_bytes() != src.read_bytes():
        shutil.copyfile(src, dst)


def write_if_changed(path: Path, text: str) -> None:
    """Write ``text`` unless the file already holds it (keeps Sphinx's incremental build)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    if not path.exists() or path.read_text() != text:
        path.write_text(text)


def _benchmark_of(path: Path, payload: dict) -> str:
    name = payload.get("benchmark")
    return str(name) if isinstance(name, str) and name else path.stem.split("_quick")[0]


def benchmark_pages(root: Path, out: Path) -> dict[str, list[str]]:
    """Write ``out/reproductions/NAME.md`` per benchmark; return family -> benchmark names."""
    records = root / "benchmarks" / "records"
    pages = out / "reproductions"
    images = pages / "img"
    images.mkdir(parents=True, exist_ok=True)
    grouped: dict[str, list[tuple[Path, dict]]] = {}
    for path in sorted(records.glob("*.json")) + sorted(records.glob("*/*.json")):
        if path.parent.name.endswith("_points") or path.stem.startswith("tradeoff"):
            continue
        try:
            payload = json.loads(path.read_text())
        except (ValueError, OSError):
            continue
        if not isinstance(payload, dict):
            continue
        grouped.setdefault(_benchmark_of(path, payload), []).append((path, payload))
    for name, files in grouped.items():
        doc = _docstring(name)
        lines = [f"# `{name}`", ""]
        module = root / "benchmarks" / f"{name}.py"
        if module.exists():
            lines += [
                f"Run: `python -m benchmarks {name} [--quick | --full] [--out DIR]` "
                f"(`benchmarks/{name}.py`). Its docstring:",
                "",
            ]
        if doc:
            lines += ["```text", doc.strip("\n"), "```", ""]
        for path, payload in files:
            lines += record_section(path, payload, images, "img", "##")
        write_if_changed(pages / f"{name}.md", "\n".join(lines))
    families: dict[str, list[str]] = {}
    placed: set[str] = set()
    for title, _, names in FAMILIES:
        families[title] = [n for n in names if n in grouped]
        placed.update(families[title])
    families["Other records"] = sorted(n for n in grouped if n not in placed)
    intro = {title: text for title, text, _ in FAMILIES}
    index = [
        "# Reproductions and benchmarks",
        "",
        "One page per benchmark, generated when the site is built from the records the "
        "benchmarks committed in `benchmarks/records/` (JSON, PNG and markdown): rerun "
        "`python -m benchmarks NAME` and commit its record, and the page follows. "
        "[The benchmark guide](../../guide/benchmarks.md) says what each one measures and how "
        "to run the long ones.",
        "",
    ]
    for title, names in families.items():
        if not names:
            continue
        index += [f"## {title}", "", intro.get(title, "Records of other benchmarks."), ""]
        index += ["```{toctree}", ":maxdepth: 1", ""] + names + ["```", ""]
    write_if_changed(pages / "index.md", "\n".join(index))
    return families


def strategy_page(root: Path, out: Path) -> None:
    """``strategy_table.md``: the capability table and the conformance summary."""
    import bfemp
    from benchmarks import conformance

    record = json.loads((root / "benchmarks" / "records" / "conformance.json").read_text())
    lines = [
        "Declared in code (`bfemp.strategy_table()`, the same text `bfemp strategies` prints):",
        "",
        "```text",
        bfemp.strategy_table(),
        "```",
        "",
        "Measured by the conformance catalogue (`benchmarks/records/conformance.json`, "
        "`python -m benchmarks conformance --full`): per scene family, how many cases kept every "
        "declared guarantee; `off:` names accuracy checks that missed their limit "
        "([every case](/generated/reproductions/conformance.md)):",
        "",
        conformance.readme_table(record),
        "",
    ]
    write_if_changed(out / "strategy_table.md", "\n".join(lines))


def _tradeoff_scene(payload: dict, scene: str, mode: str, records: Path, images: Path) -> list[str]:
    lines = [f"### {scene}", ""]
    if scene in payload.get("errors", {}):
        lines += [f"Error: {payload['errors'][scene]}", ""]
    winners = payload.get("winners", {}).get(scene) or []
    if winners:
        rows = [
            [
                w.get("error_from"),
                w.get("error_to"),
                w.get("winner"),
                w.get("cost_s"),
                w.get("runner_up"),
                w.get("runner_up_cost_s"),
            ]
            for w in winners
        ]
        lines += ["Cheapest strategy per error range:", ""] + table(
            ["error from", "error to", "winner", "cost [s]", "runner-up", "its cost [s]"], rows
        )
    points = [p for p in payload.get("points", []) if p.get("scene") == scene]
    front = sorted((p for p in points if p.get("pareto")), key=lambda p: p.get("wall_s") or 0)
    if front:
        rows = [
            [f"`{p['id']}`", p.get("error"), p.get("wall_s"), p.get("max_penetration_m")]
            for p in front
        ]
        lines += ["Non-dominated front (error against wall time):", ""] + table(
            ["point", "error", "wall [s]", "deepest penetration [m]"], rows
        )
    bad = [p for p in points if p.get("infeasible")]
    if bad:
        rows = [
            [f"`{p['id']}`", p.get("max_penetration_m"), p.get("penetration_bound_m")] for p in bad
        ]
        lines += ["Infeasible points (deeper than their strategy's bound):", ""] + table(
            ["point", "deepest penetration [m]", "bound [m]"], rows
        )
    failed = [p for p in points if p.get("failure")]
    if failed:
        lines += [
            f"Failed points: {len(failed)} ("
            + ", ".join(f"`{p['id']}`" for p in failed[:10])
            + ")",
            "",
        ]
    stem = "tradeoff" if mode == "quick" else f"tradeoff_{mode}"
    png = records / f"{stem}_{scene}.png"
    if png.exists():
        target = images / png.name
        _copy(png, target)
        lines += [f"![{png.name}](reproductions/img/{target.name})", ""]
    return lines


def tradeoff_page(root: Path, out: Path) -> None:
    """``tradeoff.md``: per mode and scene the winners, fronts and plots of the trade study."""
    records = root / "benchmarks" / "records"
    images = out / "reproductions" / "img"
    images.mkdir(parents=True, exist_ok=True)
    lines = [
        "# Trade study: accuracy against cost",
        "",
        "Generated from `benchmarks/records/tradeoff.json` (quick sweep) and "
        "`tradeoff_full.json` (full sweep) when the site is built. "
        "[Sweeps on Dask](../tutorials/sweeps_dask.md) shows how to run one.",
        "",
    ]
    for path in sorted(records.glob("tradeoff*.json")):
        payload = json.loads(path.read_text())
        mode = str(payload.get("mode", path.stem))
        executor = payload.get("executor", {})
        lines += [
            f"## {mode} sweep (`{path.name}`)",
            "",
            f"{len(payload.get('points', []))} points on {executor.get('kind', '?')} "
            f"({executor.get('workers', '?')} workers); sum of point wall times "
            f"{fmt(payload.get('point_wall_s_total'))} s, commit "
            f"`{str((payload.get('environment') or {}).get('commit', '?'))[:10]}`. "
            f"[The full report](tradeoff_report_{mode}.md) the sweep wrote.",
            "",
        ]
        for scene in payload.get("scenes", []):
            lines += _tradeoff_scene(payload, scene, mode, records, images)
        report = path.with_suffix(".md")
        if report.exists():
            write_if_changed(
                out / f"tradeoff_report_{mode}.md",
                "\n".join(
                    [
                        f"# Trade study report ({mode})",
                        "",
                        f"`benchmarks/records/{report.name}`, as the sweep wrote it:",
                        "",
                        "```{include} " + _include_path(report, out),
                        ":heading-offset: 1",
                        "```",
                        "",
                    ]
                ),
            )
    write_if_changed(out / "tradeoff.md", "\n".join(lines))


def generate(root: Path, out: Path) -> None:
    """Write every generated page of the repository at ``root`` into ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    strategy_page(root, out)
    benchmark_pages(root, out)
    tradeoff_page(root, out)


def _on_builder_inited(app: object) -> None:
    generate(Path(app.config.bfemp_root), Path(app.srcdir) / "generated")


def setup(app: object) -> dict:
    """Sphinx entry point."""
    app.add_config_value("bfemp_root", "..", "env")
    app.connect("builder-inited", _on_builder_inited)
    return {"parallel_read_safe": True, "parallel_write_safe": True, "version": "1"}
