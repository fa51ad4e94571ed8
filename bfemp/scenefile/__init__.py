"""Scene files: a coupled scene and how to run it, in TOML, one to one with the Python API.

Read with :func:`load` (a file), :func:`loads` (text) or :func:`read_scene` (the scene alone);
write with :func:`dumps` or :func:`save`. A scene written from Python reads back to the same model.
Every mistake raises :class:`~bfemp.errors.SceneError` naming the file, the body and the field.

Format (``#`` comments; numbers in SI units, scalars may also be strings with a unit such as
``dt = "2 ms"``, ``E = "50 MPa"``)::

    [scene]                       # Scene(dim, gravity)
    dim = 2
    gravity = [0.0, -9.81]

    [simulation]                  # Simulation(...) keyword arguments
    strategy = "barrier"          # coupling strategy
    integrator = "newmark"        # or "backward_euler", "newmark_damped",
                                  #    "newmark_implicit_contact"
    transfer = "apic"             # or "pic", "flip" (MPM bodies)
    dt = 0.01                     # s
    tol = 1e-6                    # Newton tolerance on ||p||_inf / dt, m/s
    max_newton_iterations = 200
    warm_start = false            # true: Newton starts from the predicted x^{n+1} (no contact)
    allow_uncoupled = false       # true: run a pair of bodies the strategy does not couple
                                  #    (refused otherwise; `bfemp strategies` lists the pairs)
    # tol, max_newton_iterations and warm_start are the barrier strategy's options written flat;
    # every strategy's options may instead be given as a table, checked field by field
    # (unknown field, wrong type, options of another strategy are refused by name):

    [simulation.options]          # bfemp.BarrierOptions(...) for "barrier", ...
    tol = "0.001 mm/s"            # numbers may carry the field's unit
    linear_solver = "default"     # or "cholmod", "scipy", "pardiso", "cg_amg", "auto"

    [run]                         # Simulation.run(...) settings; the command line may override
    t_end = 2.0                   # s
    every = 5                     # a VTK frame every 5 steps
    checkpoint_every = 50         # a checkpoint every 50 steps (0: only at the end / Ctrl-C)
    out = "results/beam"          # default output folder (relative to the working directory)

    [quick]                       # overrides of [run] for a quick check (bfemp run --quick)
    t_end = 0.1

    [materials.steel]             # named materials (or write a material table inline)
    type = "neo_hookean"          # or "linear_elastic"
    E = 5e7                       # Pa
    nu = 0.3                      # in (-1, 0.5)
    density = 1000.0              # kg/m^3
    # type = "bulk_shear" (LR eq. 18) takes K, G (Pa) and density instead of E and nu

    [grid]                        # scene.set_grid(dx, origin): the MPM background grid
    dx = 0.1
    origin = [0.0, 0.0]

    [contact]                     # scene.set_contact(...)
    dhat = 1e-3
    kappa = 1e7                   # Pa, or "auto"
    mu = 0.0
    eps_v = 1e-5
    friction_iterations = 20
    [[contact.pairs]]             # scene.set_friction(a, b, mu): mu of one pair of bodies
    bodies = ["plate", "beam"]
    mu = 10.0

    [[fem]]                       # scene.add_fem(mesh, material=, velocity=, prescribed=, ...)
    name = "beam"
    material = "steel"            # a [materials] name, or an inline table {type, E, nu, density}
    velocity = [0.0, 0.0]         # one row for every node, or one row per node
    mesh = { shape = "rectangle", lower = [0, 0], upper = [4, 0.5], h = 0.125 }
    #   shape: rectangle, box, disk, ring, semicircular_ring, spherical_shell, sine_strip with
    #   the arguments of bfemp.shapes; or mesh = { file = "beam.msh" } (read by meshio, relative
    #   to the scene file); or mesh = { points = [[x, y], ...], cells = [[i, j, k], ...] }.
    prescribed = { type = "fixed" }   # or linear {velocity}, rotation {center,
    #   angular_velocity, axis}, sequence {segments = [{duration, motion}, ...]}
    prescribed_nodes = { box = { lower = [-inf, -inf], upper = [1e-9, inf] } }
    #   or a list of node indices, or { inside = <level set> }; default: every node

    [[mpm]]                       # scene.add_mpm(particles, volumes, material=, velocity=)
    name = "block"
    material = "steel"
    particles = { sample = "box", lower = [0, 1], upper = [1, 2], ppc = 4 }
    #   sample = "box" | "mesh" (mesh = {...}) | "levelset" (levelset, lower, upper); dx and
    #   origin default to [grid]; jitter, seed. Or particles = { file = "cloud.vtu" } (a point
    #   cloud with a point field "volume"), or inline particles = [[x, y], ...] with volumes.

    [[boundary]]                  # scene.add_boundary(levelset, kind)
    kind = "slip"                 # sticky, slip or separate
    levelset = { type = "half_plane", point = [0, 0], normal = [0, 1] }
    #   or box {lower, upper}, disk {center, radius}, union {parts}, inverted {levelset}
    motion = { type = "linear", velocity = [0.0, -0.1] }   # optional: a moving boundary

    [[load]]                      # scene.add_load(body, force, nodes)
    body = "beam"
    force = [0.0, -10.0]          # N per node (N/m in 2D)
    nodes = [12, 13]              # or a selection as for prescribed_nodes; default all

    [check]                       # assertions on the run (bfemp.scenefile.checks)
    finite = true
    energy_drift_max = 0.01

    [regress]                     # a regression reference (bfemp.regress); ignored by runs
    steps = 40
"""

from __future__ import annotations

import os
import sys
from dataclasses import dataclass
from pathlib import Path

from bfemp.errors import SceneError
from bfemp.io.vtk import atomic_write_text as write_text
from bfemp.scenefile._read import TOP_LEVEL, parse_document
from bfemp.scenefile._write import dumps
from bfemp.scenefile.checks import validate_checks

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

__all__ = ["TOP_LEVEL", "SceneFile", "dumps", "load", "loads", "read_scene", "save", "write_text"]


@dataclass(frozen=True, kw_only=True)
class SceneFile:
    """A read scene file.

    Attributes:
        scene: the scene (``bfemp.Scene``), not built yet.
        simulation: ``Simulation`` keyword arguments of ``[simulation]``.
        run: ``[run]`` settings (``t_end`` s, ``every``, ``checkpoint_every``, ``out``).
        quick: ``[quick]`` overrides of ``run``.
        check: the validated ``[check]`` table.
        file: the file path (None for text).
        text: the TOML text read.
    """

    scene: object
    simulation: dict
    run: dict
    quick: dict
    check: dict
    file: str | None
    text: str

    def run_settings(self, *, quick: bool = False, t_end: float | None = None) -> dict:
        """``t_end``, ``every``, ``checkpoint_every`` (and ``out`` if given) for a run.

        Args:
            quick: apply the ``[quick]`` overrides.
            t_end: override of the end time in s.
        """
        out = {"every": 1, "checkpoint_every": 0, **self.run}
        if quick:
            out.update(self.quick)
        if t_end is not None:
            if not (isinstance(t_end, int | float) and t_end > 0):
                raise SceneError(f"must be a positive time in s, got {t_end!r}", field="--t-end")
            out["t_end"] = float(t_end)
        if "t_end" not in out:
            raise SceneError(
                "missing key 't_end'",
                file=self.file,
                field="run.t_end",
                hint="add t_end to [run] or give --t-end",
            )
        return out

    def build_model(self) -> object:
        """Build the model and check the initial configuration (errors name this file)."""
        from bfemp.validation import validate_initial

        try:
            model = self.scene.build()
            validate_initial(model)
        except SceneError as err:
            raise err.located(file=self.file) from None
        except ValueError as err:
            raise SceneError(str(err), file=self.file) from None
        return model


def loads(text: str, *, file: str | None = None, base_dir: str | Path | None = None) -> SceneFile:
    """Read a scene from TOML text.

    Args:
        text: the TOML text.
        file: name used in error messages.
        base_dir: folder that relative mesh paths start from (default: the working directory).
    """
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise SceneError(f"not valid TOML: {err}", file=file) from None
    base = None if base_dir is None else Path(base_dir)
    parsed = parse_document(data, file=file, base_dir=base)
    parsed["check"] = validate_checks(parsed["check"], file=file, dim=parsed["scene"].dim)
    return SceneFile(**parsed, file=file, text=text)  # parsed: the fields of the scene file


def load(path: str | os.PathLike) -> SceneFile:
    """Read a scene file; relative mesh paths start at the file's folder."""
    path = Path(path)
    if not path.is_file():
        raise SceneError(f"scene file not found: {path}", hint="check the path")
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as err:
        raise SceneError(f"cannot read the scene file: {err}", file=str(path)) from None
    return loads(text, file=str(path), base_dir=path.resolve().parent)


def save(
    scene: object,
    path: str | os.PathLike | None = None,
    *,
    simulation: dict | None = None,
    run: dict | None = None,
    check: dict | None = None,
) -> str:
    """A ``Scene`` as scene-file TOML text; also written to ``path`` (atomically) when given.

    Meshes and particles read from a scene file are written as they were described (shape,
    file, sampling); those given as arrays are written inline, exactly. Relative mesh paths are
    not used: files are referenced by absolute path.

    Args:
        scene: the ``bfemp.Scene``.
        path: also write the text to this file.
        simulation: ``Simulation`` keyword arguments for a ``[simulation]`` table (``options``:
            a ``StepperOptions`` or a mapping, written as ``[simulation.options]``).
        run: ``[run]`` settings (``t_end``, ``every``, ``checkpoint_every``, ``out``).
        check: a ``[check]`` table.

    Returns:
        the TOML text; ``read_scene(text)`` builds the same model.
    """
    text = dumps(scene, simulation=simulation, run=run, check=check)
    if path is not None:
        write_text(path, text)
    return text


def read_scene(source: str | os.PathLike) -> object:
    """A ``Scene`` from a scene file (a path, or a ``str`` path ending in ``.toml``) or TOML text
    (any other ``str``); the ``[simulation]`` and ``[run]`` tables are ignored here (``load``
    returns them too)."""
    if isinstance(source, os.PathLike) or (
        isinstance(source, str) and "\n" not in source and source.endswith(".toml")
    ):
        return load(source).scene
    return loads(source).scene
