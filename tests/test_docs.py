"""The documentation site builds (warnings are errors) and its generated pages hold the records.

One quick build of a copy of ``docs/`` (``BFEMP_DOCS_QUICK=1``: one gallery example runs) into
``tmp_path``, shared by the tests of this file; ``make docs`` builds the full site.
"""

from __future__ import annotations

import html
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

#: started first (tests/conftest.py): one of the suite's longest files
pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
RECORDS = ROOT / "benchmarks" / "records"

pytest.importorskip("sphinx", reason="the docs extra (pip install -e '.[docs]')")
pytest.importorskip("sphinx_gallery", reason="the docs extra (pip install -e '.[docs]')")
pytest.importorskip("myst_parser", reason="the docs extra (pip install -e '.[docs]')")


@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Build a copy of docs/ (so the checkout's generated folders stay as they are)."""
    tmp = tmp_path_factory.mktemp("docs")
    src = tmp / "src"
    shutil.copytree(
        DOCS,
        src,
        ignore=shutil.ignore_patterns(
            "_build", "generated", "auto_examples", "sg_execution_times.rst", "__pycache__"
        ),
    )
    out = tmp / "html"
    env = dict(os.environ, BFEMP_DOCS_QUICK="1", BFEMP_DOCS_ROOT=str(ROOT))
    cmd = [sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b", "html"]
    proc = subprocess.run(
        [*cmd, str(src), str(out)], env=env, capture_output=True, text=True, timeout=600
    )
    log = f"{proc.stdout[-4000:]}\n{proc.stderr[-8000:]}"
    assert proc.returncode == 0, f"sphinx-build failed:\n{log}"
    return out


def _text(page: Path) -> str:
    """The visible text of an HTML page, whitespace collapsed."""
    raw = page.read_text(encoding="utf-8")
    raw = re.sub(r"<(script|style)\b.*?</\1>", " ", raw, flags=re.S)
    return re.sub(r"\s+", " ", html.unescape(re.sub(r"<[^>]+>", " ", raw)))


def _cells(markdown_row: str) -> list[str]:
    return [c.strip() for c in markdown_row.strip().strip("|").split("|")]


def test_the_written_pages_are_built(site):
    for page in (
        "index.html",
        "getting_started.html",
        "tutorials/first_coupled_scene.html",
        "tutorials/choosing_a_strategy.html",
        "tutorials/scene_files_and_cli.html",
        "tutorials/results_and_paraview.html",
        "tutorials/regression_references.html",
        "tutorials/sweeps_dask.html",
        "guide/strategies.html",
        "guide/benchmarks.html",
    ):
        assert (site / page).is_file(), page
    assert "make demo" in _text(site / "getting_started.html")


def test_strategy_tables_are_generated_from_the_code_and_the_record(site):
    import bfemp
    from benchmarks import conformance

    text = _text(site / "tutorials" / "choosing_a_strategy.html")
    # the capabilities table, row by row, as bfemp.strategy_table() prints it now
    for line in bfemp.strategy_table().splitlines()[2:]:
        if line.startswith(tuple(bfemp.STRATEGIES)):
            assert " ".join(line.split()) in text, line
    # the conformance summary of the committed record: every row's cells
    record = json.loads((RECORDS / "conformance.json").read_text())
    rows = conformance.readme_table(record).splitlines()[2:]
    assert len(rows) == len(record["strategies"])
    for row in rows:
        cells = _cells(row)
        assert " ".join(cells) in text, row


def test_reproduction_pages_hold_the_records_numbers(site):
    rings = json.loads((RECORDS / "rings.json").read_text())
    text = _text(site / "generated" / "reproductions" / "rings.html")
    assert f"{rings['momentum_drift_rel']:.4g}" in text
    assert f"{rings['min_distance']:.4g}" in text
    assert f"{rings['energy_loss_pct']['apic']:.4g}" in text
    assert (site / "_images").is_dir() and any((site / "_images").glob("records_rings.png"))
    index = _text(site / "generated" / "reproductions" / "index.html")
    for name in ("rings", "slope", "hertz", "augury_gap", "lr_compression", "two_stage_slope"):
        assert (site / "generated" / "reproductions" / f"{name}.html").is_file(), name
        assert name in index


def test_trade_study_page_holds_the_winners_of_the_record(site):
    record = json.loads((RECORDS / "tradeoff.json").read_text())
    text = _text(site / "generated" / "tradeoff.html")
    for scene in record["scenes"]:
        assert scene in text
        for winner in record["winners"][scene]:
            assert f"{winner['cost_s']:.4g}" in text, (scene, winner)
    front = [p for p in record["points"] if p["pareto"]]
    assert front and all(p["id"] in text for p in front)


def test_gallery_example_ran_and_its_figure_is_on_the_page(site):
    page = site / "auto_examples" / "plot_shapes.html"
    raw = page.read_text(encoding="utf-8")
    images = re.findall(r'src="\.\./(_images/sphx_glr_plot_shapes_\d+\.png)"', raw)
    assert images, "no figure of plot_shapes on its page"
    png = site / images[0]
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 10_000
    # its printed output is on the page too: the sampled disk's area
    assert "particles in the disk" in _text(page)


def test_api_reference_documents_the_public_api(site):
    import bfemp

    ids = set(re.findall(r'id="([^"]+)"', (site / "api" / "bfemp.html").read_text()))
    for name in ("Scene", "Simulation", "State", "load_run", "SceneError"):
        assert f"bfemp.{name}" in ids, name
    steppers = set(re.findall(r'id="([^"]+)"', (site / "api" / "steppers.html").read_text()))
    # every registered strategy's options class, with its fields
    for cls in bfemp.STRATEGIES.values():
        assert f"bfemp.steppers.{cls.Options.__name__}" in steppers, cls
    assert "bfemp.steppers.BarrierOptions.tol" in steppers
    ccd = set(re.findall(r'id="([^"]+)"', (site / "api" / "geometry.html").read_text()))
    assert "geometry.ccd.point_triangle_ccd" in ccd


def test_readme_capability_table_is_the_codes():
    """The README's capability table is what ``bfemp.strategy_table()`` prints now."""
    import bfemp

    readme = (ROOT / "README.md").read_text()
    rows = [ln for ln in bfemp.strategy_table().splitlines() if ln.startswith("strategy ")]
    rows += [
        ln for ln in bfemp.strategy_table().splitlines() if ln.split(" ")[0] in bfemp.STRATEGIES
    ]
    assert len(rows) == len(bfemp.STRATEGIES) + 1
    for row in rows:
        assert row in readme, row


def test_readme_links_resolve_inside_the_clone():
    """Every relative link of the README names a file of the repository (GitHub renders them)."""
    readme = (ROOT / "README.md").read_text()
    links = re.findall(r"\]\(([^)#]+)\)", readme)
    local = [ln for ln in links if "://" not in ln]
    assert any(ln.startswith("docs/tutorials/") for ln in local)
    for link in local:
        assert (ROOT / link).is_file(), link
