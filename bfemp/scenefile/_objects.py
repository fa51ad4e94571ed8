"""Scene-file tables -> bfemp objects: materials, meshes, motions, level sets, node selections,
particle sets. Each reader validates its table completely and raises a located ``SceneError``."""

from __future__ import annotations

import inspect
import math
from pathlib import Path

import numpy as np

from bfemp import levelset as ls
from bfemp import motion as mo
from bfemp import sample, shapes
from bfemp._scene_inputs import node_selection
from bfemp.errors import SceneError
from bfemp.materials import BulkShearHyperelastic, LinearElastic, Material, NeoHookean
from bfemp.scenefile._fields import Table
from geometry.mesh import SourceNumbering, TetMesh, TriMesh, mesh_from_arrays, read_mesh

__all__ = [
    "MATERIAL_TYPES",
    "SHAPES",
    "read_levelset",
    "read_material",
    "read_mesh_table",
    "read_motion",
    "read_particles",
    "read_selection",
]

#: material ``type`` -> class ("linear" is accepted as an alias of "linear_elastic").
MATERIAL_TYPES = {
    "neo_hookean": NeoHookean,
    "linear_elastic": LinearElastic,
    "bulk_shear": BulkShearHyperelastic,
}
_MATERIAL_ALIASES = {"linear": "linear_elastic"}

#: mesh ``shape`` -> generator of ``bfemp.shapes``.
SHAPES = {
    name: getattr(shapes, name)
    for name in ("rectangle", "box", "disk", "ring", "semicircular_ring", "spherical_shell")
}
SHAPES["sine_strip"] = shapes.sine_strip
_SHAPE_VECTORS = {"lower", "upper", "center", "x_range"}
_SHAPE_STRINGS = {"diagonals", "profile", "other_side"}
_SAMPLE_KEYS = {"ppc", "dx", "origin", "jitter", "seed"}

_NU_HINT = (
    "nu >= 0.5 is incompressible, which these compressible materials cannot represent; "
    "use nu <= 0.49"
)


def read_material(t: Table) -> Material:
    """``{type, E, nu, density}`` -> a material (E in Pa, density in kg/m^3);
    ``{type = "bulk_shear", K, G, density}`` -> ``BulkShearHyperelastic`` (K, G in Pa)."""
    kind = t.string("type", default="neo_hookean", choices=[*MATERIAL_TYPES, *_MATERIAL_ALIASES])
    if kind == "bulk_shear":
        return _read_bulk_shear(t)
    t.check_keys({"type", "E", "nu", "density"}, required={"E", "nu", "density"})
    E = t.number(
        "E", "pressure", positive=True, hint="E is Young's modulus in Pa, e.g. 5e7 or '50 MPa'"
    )
    nu = t.number("nu")
    if not nu < 0.5:
        raise t.error(f"must be < 0.5, got {nu!r}", "nu", _NU_HINT)
    if not nu > -1.0:
        raise t.error(f"must be > -1, got {nu!r}", "nu", "Poisson's ratio lies in (-1, 0.5)")
    density = t.number(
        "density", "density", positive=True, hint="density is the mass density in kg/m^3"
    )
    cls = MATERIAL_TYPES[_MATERIAL_ALIASES.get(kind, kind)]
    return cls(E=E, nu=nu, density=density)


def _read_bulk_shear(t: Table) -> BulkShearHyperelastic:
    """``{type = "bulk_shear", K, G, density}`` -> the LR eq. (18) material."""
    t.check_keys({"type", "K", "G", "density"}, required={"K", "G", "density"})
    K = t.number(
        "K", "pressure", positive=True, hint="K is the bulk modulus in Pa, e.g. '2450 MPa'"
    )
    G = t.number(
        "G", "pressure", positive=True, hint="G is the shear modulus in Pa, e.g. '940 MPa'"
    )
    density = t.number(
        "density", "density", positive=True, hint="density is the mass density in kg/m^3"
    )
    return BulkShearHyperelastic(K=K, G=G, density=density)


def read_mesh_table(t: Table, dim: int, base_dir: Path | None) -> tuple[TriMesh | TetMesh, dict]:
    """``{shape = ..., <generator args>}``, ``{file = ...}`` or ``{points, cells}`` -> a mesh.

    Returns the mesh and the canonical table to write back (file paths made absolute).
    """
    given = [k for k in ("shape", "file", "points") if t.has(k)]
    if len(given) != 1:
        raise t.error(
            "give exactly one of 'shape' (a generated mesh), 'file' (read by meshio) or "
            f"'points' with 'cells' (inline); got {given or 'none'}"
        )
    if given[0] == "points":
        t.check_keys({"points", "cells"}, required={"points", "cells"})
        points, cells = t.array("points", np.float64, dim), t.array("cells", np.int64, dim + 1)
        try:
            mesh = mesh_from_arrays(points, cells)
        except ValueError as err:
            raise t.error(str(err)) from None
        return mesh, {"points": points.tolist(), "cells": cells.tolist()}
    if given[0] == "file":
        t.check_keys({"file"})
        path = Path(read_mesh_file_path(t, base_dir))
        try:
            mesh = read_mesh(path)
        except ValueError as err:
            raise t.error(str(err), "file") from None
        return mesh, {"file": str(path)}
    name = t.string("shape", choices=SHAPES)
    params = inspect.signature(SHAPES[name]).parameters
    required = [p for p, spec in params.items() if spec.default is inspect.Parameter.empty]
    t.check_keys({"shape", *params}, required=required)
    kwargs: dict = {}
    for key in params:
        if not t.has(key):
            continue
        if key in _SHAPE_VECTORS:
            kwargs[key] = t.vector(key, 2 if key == "x_range" else None)
        elif key in _SHAPE_STRINGS:
            kwargs[key] = t.string(key)
        else:
            kwargs[key] = t.number(key, "length", positive=key != "y_base" and key != "amplitude")
    try:
        mesh = SHAPES[name](**kwargs)
    except ValueError as err:
        raise t.error(str(err)) from None
    return mesh, {
        "shape": name,
        **{k: list(v) if isinstance(v, tuple) else v for k, v in kwargs.items()},
    }


def read_motion(t: Table, dim: int) -> mo.Motion:
    """``{type = "fixed" | "linear" | "rotation" | "sequence", ...}`` -> a motion."""
    kind = t.string("type", choices=("fixed", "linear", "rotation", "sequence"))
    if kind == "fixed":
        t.check_keys({"type"})
        return mo.Fixed()
    if kind == "linear":
        t.check_keys({"type", "velocity"}, required={"velocity"})
        return mo.Linear(velocity=t.vector("velocity", dim))
    if kind == "rotation":
        t.check_keys({"type", "center", "angular_velocity", "axis"}, {"center", "angular_velocity"})
        axis = (0.0, 0.0, 1.0)  # 2D: rotation in the plane, the axis is ignored
        if dim == 3:
            axis = t.vector("axis", 3, default=axis)
            if not any(axis):
                raise t.error("must be a non-zero 3-vector", "axis")
        return mo.Rotation(
            center=t.vector("center", dim),
            angular_velocity=t.number("angular_velocity"),
            axis=axis,
        )
    t.check_keys({"type", "segments"}, required={"segments"})
    segments = []
    for k, seg in enumerate(t.tables("segments")):
        st = Table(seg, file=t.file, body=t.body, path=f"{t.field('segments')}[{k}]")
        st.check_keys({"duration", "motion"}, required={"duration", "motion"})
        if st.raw("duration") == math.inf:
            duration = math.inf
        else:
            duration = st.number("duration", "time", positive=True)
        segments.append((duration, read_motion(st.sub("motion"), dim)))
    if not segments:
        raise t.error("must hold at least one [[...segments]] table", "segments")
    return mo.Sequence(segments=tuple(segments))


def read_levelset(t: Table, dim: int) -> object:
    """``{type = "half_plane" | "box" | "disk" | "union" | "inverted", ...}`` -> a level set."""
    kind = t.string("type", choices=("half_plane", "box", "disk", "union", "inverted"))
    try:
        if kind == "half_plane":
            t.check_keys({"type", "point", "normal"}, required={"point", "normal"})
            normal = t.vector("normal", dim)
            if not any(normal):
                raise t.error("must be non-zero", "normal")
            return ls.HalfPlane(point=t.vector("point", dim), normal=normal)
        if kind == "box":
            t.check_keys({"type", "lower", "upper"}, required={"lower", "upper"})
            return ls.Box(lower=t.vector("lower", dim), upper=t.vector("upper", dim))
        if kind == "disk":
            t.check_keys({"type", "center", "radius"}, required={"center", "radius"})
            radius = t.number("radius", "length", positive=True)
            return ls.Disk(center=t.vector("center", dim), radius=radius)
        if kind == "union":
            t.check_keys({"type", "parts"}, required={"parts"})
            parts = [
                read_levelset(Table(p, file=t.file, body=t.body, path=f"{t.path}.parts[{k}]"), dim)
                for k, p in enumerate(t.tables("parts"))
            ]
            if not parts:
                raise t.error("must hold at least one [[...parts]] table", "parts")
            return ls.Union(*parts)
        t.check_keys({"type", "levelset"}, required={"levelset"})
        return ls.Inverted(read_levelset(t.sub("levelset"), dim))
    except ValueError as err:
        if isinstance(err, SceneError):
            raise
        raise t.error(str(err)) from None


def read_selection(
    t: Table, key: str, rest: np.ndarray, numbering: SourceNumbering | None = None
) -> tuple[np.ndarray, object]:
    """Nodes selected by ``key``: a list of indices, ``{box = {lower, upper}}`` (closed box,
    bounds may be +-inf) or ``{inside = <level set>}`` (value <= 0), at rest positions ``rest
    (n, d)`` m. Indices are in the numbering of the mesh file when ``numbering`` is given (a
    file with points that no cell uses: they were pruned; their indices are refused). Returns
    a bool mask ``(n,)`` and the canonical value to write back."""
    n, dim = rest.shape
    value = t.raw(key)
    if isinstance(value, list):
        idx = t.array(key, np.int64)
        if idx.size == 0:
            raise t.error("selects no node (an empty list)", key, "list at least one node")
        mask = np.zeros(n, dtype=bool)
        try:
            mask[node_selection(idx, n, "node", numbering)] = True
        except ValueError as err:
            raise t.error(str(err), key) from None
        return mask, idx.tolist()
    s = t.sub(key)
    s.check_keys({"box", "inside"})
    if len(s.data) != 1:
        raise s.error("give a list of node indices, or exactly one of 'box' or 'inside'")
    if s.has("box"):
        b = s.sub("box")
        b.check_keys({"lower", "upper"}, required={"lower", "upper"})
        lo, hi = b.vector("lower", dim, finite=False), b.vector("upper", dim, finite=False)
        if any(math.isnan(v) for v in lo + hi):
            raise b.error("bounds must not be NaN (use inf or -inf for an open side)")
        mask = np.all((rest >= np.array(lo)) & (rest <= np.array(hi)), axis=1)
        canonical: object = {"box": {"lower": list(lo), "upper": list(hi)}}
    else:
        inside = read_levelset(s.sub("inside"), dim)
        mask = np.asarray(inside.value(rest)) <= 0.0
        canonical = {"inside": s.data["inside"]}
    if not mask.any():
        lo, hi = rest.min(axis=0).tolist(), rest.max(axis=0).tolist()
        raise t.error("selects no node", key, f"the body's nodes span {lo} to {hi} m")
    return mask, canonical


def read_particles(
    t: Table, dim: int, grid: tuple[float, tuple[float, ...]] | None, base_dir: Path | None
) -> tuple[np.ndarray, np.ndarray, dict]:
    """``particles = {sample = "box" | "mesh" | "levelset", ...}`` or ``{file = ...}`` ->
    positions ``(p, d)`` m, volumes ``(p,)`` m^d and the canonical table."""
    if t.has("file"):
        t.check_keys({"file"})
        path = Path(read_mesh_file_path(t, base_dir))
        return (*_particles_from_file(t, path, dim), {"file": str(path)})
    kind = t.string("sample", choices=("box", "mesh", "levelset"))
    where = {
        "box": {"lower", "upper"},
        "mesh": {"mesh"},
        "levelset": {"levelset", "lower", "upper"},
    }
    t.check_keys({"sample", *_SAMPLE_KEYS, *where[kind]}, required={"ppc", *where[kind]})
    if grid is None and not t.has("dx"):
        raise t.error("missing key 'dx'", "dx", "give particles.dx or add a [grid] table")
    dx = t.number("dx", "length", positive=True) if t.has("dx") else grid[0]
    origin = t.vector("origin", dim) if t.has("origin") else (grid[1] if grid else None)
    opts = dict(
        jitter=t.number("jitter", default=0.0),
        rng=t.integer("seed", default=0, minimum=0),
        origin=origin,
    )
    canonical = {k: v for k, v in t.data.items() if k not in ("mesh",)}
    try:
        if kind == "box":
            lo, hi = t.vector("lower", dim), t.vector("upper", dim)
            x, vol = sample.box(lo, hi, dx, t.integer("ppc"), **opts)
        elif kind == "mesh":
            mesh, mesh_canonical = read_mesh_table(t.sub("mesh"), dim, base_dir)
            canonical["mesh"] = mesh_canonical
            x, vol = sample.mesh(mesh, dx, t.integer("ppc"), **opts)
        else:
            shape = read_levelset(t.sub("levelset"), dim)
            lo, hi = t.vector("lower", dim), t.vector("upper", dim)
            x, vol = sample.levelset(shape, lo, hi, dx, t.integer("ppc"), **opts)
    except ValueError as err:
        if isinstance(err, SceneError):
            raise
        raise t.error(str(err)) from None
    return x, vol, canonical


def read_mesh_file_path(t: Table, base_dir: Path | None) -> str:
    """The absolute path of ``t.file``; error when it does not exist."""
    path = Path(t.string("file")).expanduser()
    if not path.is_absolute():
        path = (base_dir or Path.cwd()) / path
    if not path.is_file():
        where = f"relative paths start at {base_dir or Path.cwd()}"
        raise t.error(f"file not found: {path}", "file", f"check the path ({where})")
    return str(path.resolve())


def _particles_from_file(t: Table, path: Path, dim: int) -> tuple[np.ndarray, np.ndarray]:
    """Points and the point field ``volume`` of a meshio point cloud (e.g. a bfemp frame)."""
    import meshio

    try:
        cloud = meshio.read(path)
    except Exception as err:  # meshio raises many types for a bad file
        raise t.error(f"cannot read {path}: {err}", "file") from None
    x = np.asarray(cloud.points, dtype=np.float64)
    if dim == 2 and x.shape[1] == 3 and np.all(x[:, 2] == 0.0):
        x = x[:, :2]
    if x.shape[1] != dim:
        raise t.error(f"{path} holds {x.shape[1]}D points but the scene is {dim}D", "file")
    if "volume" not in cloud.point_data:
        raise t.error(f"{path} has no point field 'volume' (particle volumes in m^{dim})", "file")
    return np.ascontiguousarray(x), np.asarray(cloud.point_data["volume"], dtype=np.float64)
