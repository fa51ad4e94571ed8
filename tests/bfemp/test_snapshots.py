"""Snapshot pictures: round-off is not coloured as stress; panel titles never overlap."""

import warnings

import numpy as np
import pytest
from matplotlib import colormaps

import bfemp
from bfemp.io.snapshots import (
    BodyView,
    Snapshot,
    snapshot_figure,
    snapshot_from_blocks,
    write_snapshot_sheet,
)

STRESS_FLOOR_PA = 1.0
ZERO_COLOUR = colormaps["viridis"](0.0)


def _strip(width, height, nx=21, ny=3):
    """A ``width x height`` m rectangle of ``2 (nx - 1)(ny - 1)`` triangles: points, cells."""
    xs, ys = np.meshgrid(np.linspace(0.0, width, nx), np.linspace(0.0, height, ny))
    points = np.stack([xs.ravel(), ys.ravel()], axis=1)
    a = (np.arange(ny - 1)[:, None] * nx + np.arange(nx - 1)[None, :]).ravel()
    cells = np.concatenate(
        [np.stack([a, a + 1, a + nx + 1], 1), np.stack([a, a + nx + 1, a + nx], 1)]
    )
    return points, cells


def _face_colours(fig, name_index=0):
    """RGBA ``(m, 4)`` of the cells of the ``name_index``-th mesh in the first panel."""
    fig.canvas.draw()
    return fig.axes[0].collections[name_index].get_facecolor()


def test_a_fixed_plate_alone_is_drawn_in_the_colour_of_zero_stress(tmp_path):
    """A fixed 200 MPa plate that nothing touches: its von Mises stress is round-off
    (~1e-7 Pa), which must not fill the colour scale."""
    mesh = bfemp.shapes.rectangle((0.0, 0.0), (1.0, 0.1), h=0.05)
    scene = bfemp.Scene(dim=2, gravity=(0.0, -9.81))
    steel = bfemp.NeoHookean(E=2e8, nu=0.3, density=7800.0)
    scene.add_fem(mesh, material=steel, name="plate", prescribed=bfemp.motion.Fixed())
    sim = bfemp.Simulation(scene, dt=1e-3)
    snaps = [snapshot_from_blocks(sim.state.t, sim.frame_blocks())]
    sim.step()
    snaps.append(snapshot_from_blocks(sim.state.t, sim.frame_blocks()))
    vm = np.concatenate([s.bodies[0].von_mises for s in snaps])
    assert 0.0 < vm.max() < 1e-3 * STRESS_FLOOR_PA  # round-off, not zero: the case at hand
    fig = snapshot_figure(snaps)
    assert np.allclose(_face_colours(fig), ZERO_COLOUR, atol=2e-3)
    label = fig.axes[-1].get_ylabel()
    assert "floored at 1 Pa" in label and f"max {vm.max():.2g}" in label
    assert write_snapshot_sheet(tmp_path, snapshots=snaps).exists()


def test_round_off_beside_real_stress_is_zero_and_the_scale_is_the_real_one():
    points, cells = _strip(1.0, 0.1)
    noise = 4e-8 * np.random.default_rng(0).random(len(cells))
    stress = np.linspace(0.0, 2e5, len(cells))
    snap = Snapshot(
        0.0,
        (
            BodyView("plate", points, cells, noise),
            BodyView("block", points + [0.0, 0.5], cells, stress),
        ),
    )
    fig = snapshot_figure([snap])
    assert np.allclose(_face_colours(fig, 0), ZERO_COLOUR, atol=2e-3)
    assert fig.axes[-1].get_ylabel() == "von Mises stress [Pa]"  # not floored
    assert fig.axes[-1].get_ylim()[1] == pytest.approx(2e5)
    top = _face_colours(fig, 1)[np.argmax(stress)]
    assert np.allclose(top, colormaps["viridis"](1.0), atol=2e-3)


def test_the_floor_can_be_switched_off_and_bad_floors_are_refused(tmp_path):
    points, cells = _strip(1.0, 0.1)
    noise = 4e-8 * np.linspace(0.0, 1.0, len(cells))
    snap = Snapshot(0.0, (BodyView("plate", points, cells, noise),))
    fig = snapshot_figure([snap], stress_floor=0.0)  # the bare scale: 0 to 4e-8 Pa
    assert fig.axes[-1].get_ylim()[1] == pytest.approx(4e-8)
    assert np.allclose(_face_colours(fig)[-1], colormaps["viridis"](1.0), atol=2e-3)
    for bad in (-1.0, float("nan"), "1 Pa"):
        with pytest.raises(ValueError, match="stress_floor"):
            snapshot_figure([snap], stress_floor=bad)
        with pytest.raises(ValueError, match="stress_floor"):
            write_snapshot_sheet(tmp_path, snapshots=[snap], stress_floor=bad)


def _title_clashes(fig):
    """(panel title, what it overlaps) for every panel title whose box, as drawn by the Agg
    renderer, overlaps another axes (its plot, ticks, labels or title), or the sheet title."""
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    panels = [ax for ax in fig.axes if ax.get_title().startswith("t = ")]
    clashes = []
    for ax in panels:
        box = ax.title.get_window_extent(renderer)
        for other in fig.axes:
            if other is not ax and box.overlaps(other.get_tightbbox(renderer)):
                clashes.append((ax.get_title(), other.get_title() or other.get_ylabel()))
        if box.overlaps(fig.get_suptitle() and fig._suptitle.get_window_extent(renderer)):
            clashes.append((ax.get_title(), "sheet title"))
    return panels, clashes


@pytest.mark.parametrize(
    ("n", "width", "height"),
    [
        (4, 4.0, 1.1),  # the cantilever sheet of `bfemp run examples/cantilever.toml --quick`
        (6, 4.0, 1.1),
        (6, 20.0, 1.0),  # wide
        (6, 1.0, 20.0),  # tall
        (5, 1.0, 1.0),
    ],
)
def test_panel_titles_overlap_no_other_panel_nor_each_other(n, width, height):
    points, cells = _strip(width, height, *((21, 3) if width >= height else (3, 21)))
    snaps = [
        Snapshot(
            0.0123456 * k,
            (BodyView("beam", points, cells, np.linspace(0.0, 1e5 * (k + 1), len(cells))),),
        )
        for k in range(n)
    ]
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # e.g. constrained layout giving up: "axes sizes collapsed"
        panels, clashes = _title_clashes(snapshot_figure(snaps))
    assert len(panels) == n
    assert clashes == []
