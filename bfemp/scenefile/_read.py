"""A parsed scene file (a dict from ``tomllib``) -> ``Scene`` plus run settings.

The tables map one to one onto the Python API (see :mod:`bfemp.scenefile` for the reference).
Every mistake raises :class:`~bfemp.errors.SceneError` naming the file, the body and the field.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from bfemp.errors import SceneError
from bfemp.integrators import INTEGRATOR_NAMES
from bfemp.scene import Scene, check_fem_mesh
from bfemp.scenefile._fields import Table
from bfemp.scenefile._objects import (
    read_levelset,
    read_material,
    read_mesh_table,
    read_motion,
    read_particles,
    read_selection,
)
from bfemp.steppers import STRATEGIES, options_from_mapping

__all__ = ["TOP_LEVEL", "parse_document"]

#: the tables a scene file may hold.
TOP_LEVEL = (
    "scene",
    "materials",
    "fem",
    "mpm",
    "grid",
    "contact",
    "boundary",
    "load",
    "simulation",
    "run",
    "quick",
    "check",
    "regress",  # a regression reference's settings, read by bfemp.regress
)
TRANSFERS = ("apic", "pic", "flip")
_INIT_HINTS = {
    "inverted": "cells must be counter-clockwise (2D) / right-handed (3D); flip the last two "
    "vertices of the listed cells, or fix the mesh generator",
    "aspect ratio": "re-mesh with better-shaped cells; a rigid body can keep them if every node "
    "is prescribed",
    "degenerate": "remove or repair the cells of (near) zero area or volume",
}


def _strip(message: str, body: str) -> str:
    """``message`` without a leading ``"<body>: "`` (the location is added again)."""
    return message[len(body) + 2 :] if message.startswith(body + ": ") else message


def _api_error(err: ValueError, t: Table, field: str | None, body: str | None) -> SceneError:
    if isinstance(err, SceneError):
        return err
    msg = _strip(str(err), body or "")
    hint = next((h for word, h in _INIT_HINTS.items() if word in msg), None)
    return SceneError(msg, file=t.file, body=body, field=field, hint=hint)


def _material(t: Table, materials: dict) -> tuple[object, str | None]:
    value = t.raw("material")
    if isinstance(value, str):
        if value not in materials:
            known = ", ".join(sorted(materials)) or "none defined"
            raise t.error(
                f"unknown material '{value}' (materials: {known})",
                "material",
                f"define it in a [materials.{value}] table, or write the material inline",
            )
        return materials[value], value
    return read_material(t.sub("material")), None


def _velocity(t: Table, dim: int, n: int, n_file: int | None = None) -> np.ndarray | tuple | None:
    """One velocity or one row per node (``n``, or ``n_file``: per point of the mesh file)."""
    if not t.has("velocity"):
        return None
    value = t.raw("velocity")
    if isinstance(value, list) and value and isinstance(value[0], list):
        v = t.array("velocity", np.float64, dim)
        if v.shape[0] not in (n, n_file):
            rows = f"{n} (or {n_file}, the points of the file)" if n_file else f"{n}"
            raise t.error(
                f"must have 1 or {rows} rows of {dim} numbers, got {v.shape[0]}", "velocity"
            )
        return v
    return t.vector("velocity", dim)


def _add_fem(scene: Scene, spec: dict, k: int, materials: dict, ctx: dict) -> None:
    name = spec.get("name", f"fem{k}")
    body = f"fem body '{name}'"
    t = Table(spec, file=ctx["file"], body=body)
    keys = {"name", "mesh", "material", "velocity", "prescribed", "prescribed_nodes"}
    t.check_keys(keys, required={"mesh", "material"})
    name = t.string("name", default=name)
    mesh, mesh_source = read_mesh_table(t.sub("mesh"), scene.dim, ctx["base_dir"])
    numbering = mesh.source if mesh.source is not None and mesh.source.pruned else None
    motion = read_motion(t.sub("prescribed"), scene.dim) if t.has("prescribed") else None
    nodes, nodes_source = None, None
    if t.has("prescribed_nodes"):
        if motion is None:
            raise t.error(
                "given without a prescribed motion", "prescribed_nodes", "add prescribed = {...}"
            )
        nodes, nodes_source = read_selection(t, "prescribed_nodes", mesh.points, numbering)
    rigid = motion is not None and (nodes is None or bool(nodes.all()))
    try:
        mesh = check_fem_mesh(mesh, "mesh", rigid=rigid)
    except ValueError as err:
        raise _api_error(ValueError(str(err).removeprefix("mesh: ")), t, "mesh", body) from None
    material, material_name = _material(t, materials)
    n_file = numbering.n_source if numbering is not None else None
    velocity = _velocity(t, scene.dim, mesh.n_points, n_file)
    try:
        scene.add_fem(
            mesh,
            material=material,
            velocity=velocity,
            prescribed=motion,
            prescribed_nodes=nodes,
            name=name,
        )
    except ValueError as err:
        raise _api_error(err, t, None, body) from None
    ctx["fem"].append((name, mesh.points, numbering))
    scene._record_source(name, "mesh", mesh_source)
    scene._record_source(name, "material", material_name)
    scene._record_source(name, "prescribed_nodes", nodes_source)


def _add_mpm(scene: Scene, spec: dict, k: int, materials: dict, ctx: dict) -> None:
    name = spec.get("name", f"mpm{k}")
    body = f"mpm body '{name}'"
    t = Table(spec, file=ctx["file"], body=body)
    t.check_keys(
        {"name", "particles", "volumes", "material", "velocity"}, {"particles", "material"}
    )
    name = t.string("name", default=name)
    source = None
    if isinstance(t.raw("particles"), list):
        x = t.array("particles", np.float64, scene.dim)
        vol = t.array("volumes", np.float64)
    else:
        if t.has("volumes"):
            raise t.error("is only used with inline particle positions", "volumes")
        x, vol, source = read_particles(t.sub("particles"), scene.dim, ctx["grid"], ctx["base_dir"])
    material, material_name = _material(t, materials)
    velocity = _velocity(t, scene.dim, x.shape[0])
    try:
        scene.add_mpm(x, vol, material=material, velocity=velocity, name=name)
    except ValueError as err:
        raise _api_error(err, t, None, body) from None
    scene._record_source(name, "particles", source)
    scene._record_source(name, "material", material_name)


def _add_load(scene: Scene, spec: dict, k: int, ctx: dict) -> None:
    t = Table(spec, file=ctx["file"], path=f"load[{k}]")
    t.check_keys({"body", "force", "nodes"}, required={"body", "force"})
    names = [name for name, _, _ in ctx["fem"]]
    mpm_names = [spec.name for spec in scene._mpm]
    if t.raw("body") in mpm_names:
        raise t.error(
            f"loads act on FEM bodies only, and '{t.raw('body')}' is an MPM body",
            "body",
            "MPM bodies feel body forces through [scene] gravity",
        )
    if not names:
        raise t.error("loads act on fem bodies, but the scene has none")
    name = t.string("body", choices=names)
    index = names.index(name)
    _, rest, numbering = ctx["fem"][index]
    force = t.raw("force")
    if isinstance(force, list) and force and isinstance(force[0], list):
        f = t.array("force", np.float64, scene.dim)
    else:
        f = np.array(t.vector("force", scene.dim))
    nodes = None
    if isinstance(t.raw("nodes", None), list):  # indices keep their order (rows of force)
        nodes = t.array("nodes", np.int64)  # in the mesh file's numbering: add_load maps them
        read_selection(t, "nodes", rest, numbering)  # range check
    elif t.has("nodes"):
        nodes = read_selection(t, "nodes", rest)[0]
    try:
        scene.add_load(index, f, nodes)
    except ValueError as err:
        raise _api_error(err, t, "force", f"fem body '{name}'") from None


def _simulation(root: Table) -> dict:
    if not root.has("simulation"):
        return {}
    t = root.sub("simulation")
    hint = "dt is the time step in s, or 'auto' (an explicit strategy's stable step)"
    readers = {  # key -> its reader (each key optional)
        "strategy": lambda k: t.string(k, choices=STRATEGIES),
        "integrator": lambda k: t.string(k, choices=INTEGRATOR_NAMES),
        "transfer": lambda k: t.string(k, choices=TRANSFERS),
        "dt": lambda k: (
            "auto" if t.raw(k) == "auto" else t.number(k, "time", positive=True, hint=hint)
        ),
        "tol": lambda k: t.number(k, "velocity", positive=True),
        "max_newton_iterations": lambda k: t.integer(k, minimum=1),
        "warm_start": t.boolean,
        "allow_uncoupled": t.boolean,
    }
    t.check_keys({*readers, "options"})
    out = {key: read(key) for key, read in readers.items() if t.has(key)}
    if t.has("options"):
        out["options"] = _options(t.sub("options"), out.get("strategy", "barrier"))
    return out


def _options(t: Table, strategy: str) -> object:
    """``[simulation.options]``: the strategy's options; numbers may carry the field's unit."""
    cls = STRATEGIES[strategy].Options
    kinds = {f.name: f.metadata.get("unit") for f in dataclasses.fields(cls)}
    values = {}
    for key, value in t.data.items():
        if kinds.get(key) and isinstance(value, str):
            value = t.number(key, kinds[key])
        values[key] = value
    try:
        return options_from_mapping(cls, values, where=t.field() or "simulation.options")
    except ValueError as err:
        raise SceneError(str(err), file=t.file, field=t.field()) from None


def _run(root: Table, key: str) -> dict:
    if not root.has(key):
        return {}
    t = root.sub(key)
    readers = {
        "t_end": lambda k: t.number(k, "time", positive=True),
        "every": lambda k: t.integer(k, minimum=1),
        "checkpoint_every": lambda k: t.integer(k, minimum=0),
        "out": t.string,
    }
    t.check_keys(set(readers) - ({"out"} if key == "quick" else set()))
    return {key: read(key) for key, read in readers.items() if t.has(key)}


def parse_document(data: dict, *, file: str | None, base_dir: Path | None) -> dict:
    """Build the scene and read the settings of a parsed scene file.

    Returns:
        dict with ``scene`` (a ``Scene``), ``simulation`` (``Simulation`` keyword arguments),
        ``run`` and ``quick`` (``run`` settings and their quick overrides) and ``check`` (the raw
        ``[check]`` table, validated by :mod:`bfemp.scenefile.checks`).
    """
    root = Table(data, file=file)
    root.check_keys(TOP_LEVEL, required={"scene"})
    st = root.sub("scene")
    st.check_keys({"dim", "gravity"}, required={"dim"})
    dim = st.integer("dim")
    if dim not in (2, 3):
        raise st.error(f"must be 2 or 3, got {dim}", "dim")
    scene = Scene(dim=dim, gravity=st.vector("gravity", dim, default=None))
    mats = root.sub("materials", default_empty=True)
    materials = {name: read_material(mats.sub(name)) for name in mats.data}
    grid = None
    if root.has("grid"):
        gt = root.sub("grid")
        gt.check_keys({"dx", "origin"}, required={"dx"})
        grid = (gt.number("dx", "length", positive=True), gt.vector("origin", dim, default=None))
        try:
            scene.set_grid(grid[0], grid[1])
        except ValueError as err:
            raise _api_error(err, gt, None, None) from None
        grid = (grid[0], grid[1] or (0.0,) * dim)
    ctx = {"file": file, "base_dir": base_dir, "grid": grid, "fem": []}
    for k, spec in enumerate(root.tables("fem")):
        _add_fem(scene, spec, k, materials, ctx)
    for k, spec in enumerate(root.tables("mpm")):
        _add_mpm(scene, spec, k, materials, ctx)
    if root.has("contact"):
        ct = root.sub("contact")
        ct.check_keys({"dhat", "kappa", "mu", "eps_v", "friction_iterations", "pairs"}, {"dhat"})
        hint = 'kappa is the barrier stiffness in Pa (e.g. 1e7 or "10 MPa"), or "auto"'
        readers = {
            "dhat": lambda k: ct.number(k, "length", positive=True),
            "kappa": lambda k: (
                "auto"
                if ct.raw(k) == "auto"
                else ct.number(k, "pressure", positive=True, hint=hint)
            ),
            "mu": lambda k: ct.number(k, minimum=0.0),
            "eps_v": lambda k: ct.number(k, "velocity", positive=True),
            "friction_iterations": lambda k: ct.integer(k, minimum=1),
        }
        kw = {key: read(key) for key, read in readers.items() if ct.has(key)}
        try:
            scene.set_contact(**kw)
        except ValueError as err:
            raise _api_error(err, ct, None, None) from None
        for k, spec in enumerate(ct.tables("pairs")):  # [[contact.pairs]]: set_friction
            pt = Table(spec, file=file, path=f"contact.pairs[{k}]")
            pt.check_keys({"bodies", "mu"}, required={"bodies", "mu"})
            bodies = pt.raw("bodies")
            pair = isinstance(bodies, list) and len(bodies) == 2
            if not (pair and all(isinstance(b, str) for b in bodies)):
                raise pt.error(f"must be a list of two body names, got {bodies!r}", "bodies")
            try:
                scene.set_friction(bodies[0], bodies[1], pt.number("mu", minimum=0.0))
            except ValueError as err:
                raise _api_error(err, pt, "bodies", None) from None
    for k, spec in enumerate(root.tables("boundary")):
        bt = Table(spec, file=file, path=f"boundary[{k}]")
        bt.check_keys({"kind", "levelset", "motion"}, required={"levelset"})
        kind = bt.string("kind", default="slip", choices=("sticky", "slip", "separate"))
        shape = read_levelset(bt.sub("levelset"), dim)
        motion = read_motion(bt.sub("motion"), dim) if bt.has("motion") else None
        try:
            scene.add_boundary(shape, kind=kind, motion=motion)
        except ValueError as err:
            raise _api_error(err, bt, "motion" if motion else None, None) from None
    for k, spec in enumerate(root.tables("load")):
        _add_load(scene, spec, k, ctx)
    return {
        "scene": scene,
        "simulation": _simulation(root),
        "run": _run(root, "run"),
        "quick": _run(root, "quick"),
        "check": root.sub("check", default_empty=True).data,
    }
