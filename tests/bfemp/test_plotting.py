"""PNG plots: files are valid, non-trivial images; groups resolve against the log's columns."""

import math
import subprocess
import sys

import matplotlib.image
import numpy as np
import pytest

from bfemp.io import MetricsLog
from bfemp.plotting import metrics_figure, plot_metrics, plot_series

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def _log(n=30):
    t = np.linspace(0.0, 0.3, n)
    rows = [
        {
            "t": t[i],
            "energy_kinetic": 0.5 * np.cos(10 * t[i]) ** 2,
            "energy_elastic": 0.5 * np.sin(10 * t[i]) ** 2,
            "momentum_x": 1.0,
            "momentum_y": -9.81 * t[i],
            "iterations_newton": 2 + i % 4,
            "time_assembly": 1e-3 * (1 + i % 3),
            "min_distance": 1e-3,
        }
        for i in range(n)
    ]
    return MetricsLog(rows)


def _assert_real_png(path, min_size=(200, 200)):
    data = path.read_bytes()
    assert data[:8] == PNG_MAGIC
    assert len(data) > 5000
    image = matplotlib.image.imread(path)
    assert image.shape[0] >= min_size[0] and image.shape[1] >= min_size[1]
    # Curves and text, not a blank canvas: many distinct colours.
    assert len(np.unique(image.reshape(-1, image.shape[-1]), axis=0)) > 20
    assert [p for p in path.parent.iterdir() if p.name.endswith(".tmp")] == []


def test_plot_metrics_writes_png_with_one_panel_per_group(tmp_path):
    log = _log()
    path = plot_metrics(log, tmp_path / "plots" / "metrics.png", title="two rings")
    _assert_real_png(path)
    fig = metrics_figure(log)
    titles = [ax.get_title() for ax in fig.axes]
    assert titles == ["energies", "momenta", "iterations", "min distance", "timings"]
    labels = [[line.get_label() for line in ax.get_lines()] for ax in fig.axes]
    assert labels == [
        ["energy_kinetic", "energy_elastic"],
        ["momentum_x", "momentum_y"],
        ["iterations_newton"],
        ["min_distance"],
        ["time_assembly"],
    ]
    np.testing.assert_array_equal(fig.axes[0].get_lines()[0].get_xdata(), log.column("t"))
    # Panels share the x axis; the bottom one carries its label.
    assert fig.axes[-1].get_xlabel() == "t [s]"


def test_plot_metrics_skips_absent_groups_and_takes_custom_groups(tmp_path):
    log = MetricsLog([{"t": 0.1 * i, "energy_total": 1.0 - 0.01 * i} for i in range(10)])
    fig = metrics_figure(log)
    assert [ax.get_title() for ax in fig.axes] == ["energies"]
    fig = metrics_figure(
        _log(), x=None, groups={"contact": ["min_distance", "absent"], "gone": ["nothing_*"]}
    )
    assert [ax.get_title() for ax in fig.axes] == ["contact"]
    np.testing.assert_array_equal(fig.axes[0].get_lines()[0].get_xdata(), np.arange(30))
    assert fig.axes[0].get_xlabel() == "step"
    _assert_real_png(plot_metrics(log, tmp_path / "m.png"))


def test_plot_metrics_rejects_bad_input(tmp_path):
    log = _log()
    with pytest.raises(ValueError, match="x column 'time'"):
        plot_metrics(log, tmp_path / "a.png", x="time")
    with pytest.raises(ValueError, match="log is empty"):
        plot_metrics(MetricsLog(), tmp_path / "a.png")
    with pytest.raises(ValueError, match="no column of the log matches"):
        plot_metrics(log, tmp_path / "a.png", groups={"g": ["zzz"]})
    with pytest.raises(ValueError, match="groups\\['g'\\] must be a non-empty list"):
        plot_metrics(log, tmp_path / "a.png", groups={"g": "energy_kinetic"})
    assert not (tmp_path / "a.png").exists()


def test_plot_series_log_axes_and_validation(tmp_path):
    h = np.logspace(-3, -1, 5)
    path = plot_series(
        h,
        {"error": 3.0 * h**2, "reference O(h^2)": h**2},
        tmp_path / "conv.png",
        "h [m]",
        "error",
        "convergence",
        logy=True,
        logx=True,
    )
    _assert_real_png(path)
    with pytest.raises(ValueError, match="ys\\['bad'\\] has shape \\(4,\\)"):
        plot_series(h, {"bad": h[:4]}, tmp_path / "x.png")
    with pytest.raises(ValueError, match="x must have shape"):
        plot_series(np.zeros((2, 2)), {"a": np.zeros(2)}, tmp_path / "x.png")
    with pytest.raises(ValueError, match="ys must be a non-empty mapping"):
        plot_series(h, {}, tmp_path / "x.png")


def test_plot_overwrite_is_atomic(tmp_path, monkeypatch):
    log = _log()
    path = plot_metrics(log, tmp_path / "m.png")
    before = path.read_bytes()
    from matplotlib.figure import Figure

    def broken_savefig(self, fname, **kwargs):
        with open(fname, "wb") as f:
            f.write(b"partial")
        raise OSError("disk full")

    monkeypatch.setattr(Figure, "savefig", broken_savefig)
    with pytest.raises(OSError, match="disk full"):
        plot_metrics(log, path)
    assert path.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["m.png"]


def test_plotting_does_not_import_pyplot(tmp_path):
    # Building and saving figures must leave pyplot (global backend state) untouched.
    code = (
        "import sys\n"
        "from bfemp.io import MetricsLog\n"
        "before = 'matplotlib.pyplot' in sys.modules\n"
        "from bfemp.plotting import plot_metrics\n"
        f"plot_metrics(MetricsLog([{{'t': 0.0, 'energy_a': 1.0}}]), {str(tmp_path / 'a.png')!r})\n"
        "assert before or 'matplotlib.pyplot' not in sys.modules, 'pyplot imported'\n"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    assert (tmp_path / "a.png").read_bytes()[:8] == PNG_MAGIC


def test_plot_bars_writes_a_png_and_rejects_mismatched_groups(tmp_path):
    from bfemp.plotting import plot_bars

    path = plot_bars(["a", "b"], {"x": [1.0, 2.0], "y": [0.5, float("nan")]}, tmp_path / "b.png")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    with pytest.raises(ValueError, match="groups\\['x'\\]"):
        plot_bars(["a", "b"], {"x": [1.0]}, tmp_path / "c.png")


def test_metrics_figure_is_readable_at_a_glance():
    """Every curve of a panel has its own colour, every axis a unit, legends beside the axes."""
    phases = [f"time_{p}" for p in "abcdefghijkl"]  # 12 timing curves, as a contact run has
    rows = [
        {
            "t": 0.01 * i,
            "energy_kinetic": 1.0,
            "energy_elastic": 2.0,
            "energy_total": 3.0,
            "momentum_x": 0.1 * i,
            "momentum_y": 0.0,
            "min_distance": 1e-3,
            **{p: 1e-3 * (k + 1) for k, p in enumerate(phases)},
        }
        for i in range(20)
    ]
    fig = metrics_figure(MetricsLog(rows))
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    for ax in fig.axes:
        styles = [(line.get_color(), line.get_linestyle()) for line in ax.get_lines()]
        assert len(set(styles)) == len(styles), (ax.get_title(), styles)
        assert "[" in ax.get_ylabel() or "iterations" in ax.get_ylabel(), ax.get_title()
        legend = ax.get_legend()
        if legend is not None:  # right of the axes box: over no curve and no tick label
            assert legend.get_window_extent(renderer).x0 >= ax.get_window_extent(renderer).x1
    timings = fig.axes[-1]
    assert len(timings.get_lines()) == 12 and timings.get_yscale() == "log"
    assert fig.axes[-1].get_xlabel() == "t [s]"
    assert fig.axes[0].get_ylabel().startswith("energy [J]")


def test_a_panel_of_columns_the_run_does_not_compute_says_why_it_is_empty():
    """An explicit strategy's ``min_distance`` (and a strategy's ``energy_contact``) is NaN in
    every row: the panel was drawn empty without a word (issue 42, defect 3)."""
    log = MetricsLog(
        {**row, "energy_contact": math.nan, "min_distance": math.nan} for row in _log(5).rows
    )
    fig = metrics_figure(log)
    panels = {ax.get_title(): ax for ax in fig.axes}
    empty = panels["min distance"]
    assert [t.get_text() for t in empty.texts] == [
        "min_distance: not computed in this run: NaN in every row"
    ]
    energies = panels["energies"]
    labels = energies.get_legend_handles_labels()[1]
    assert "energy_contact (not computed in this run: NaN in every row)" in labels
    assert "energy_kinetic" in labels and not energies.texts  # computed columns: as before
    # the control: a column that went NaN after finite rows is plotted as it is, unlabelled
    broken = MetricsLog(
        {**row, "min_distance": math.nan if i else 1e-3} for i, row in enumerate(_log(5).rows)
    )
    assert not {ax.get_title(): ax for ax in metrics_figure(broken).axes}["min distance"].texts
