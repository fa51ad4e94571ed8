"""``Scene`` -> scene-file text: the plain dict of a scene file, written as TOML by :mod:`._toml`.

What a scene file described (mesh shapes and files, particle sampling, node selections, material
names) is written back as it was; what came from arrays is written inline: floats are written
with ``repr``, so positions, volumes and velocities read back bit for bit. Level sets and motions
are written from their parameters (a normalised direction is written normalised).
"""

from __future__ import annotations

import numpy as np

from bfemp import levelset as ls
from bfemp import motion as mo
from bfemp.errors import SceneError
from bfemp.materials import BulkShearHyperelastic, LinearElastic, NeoHookean
from bfemp.scenefile._toml import dumps as dumps_toml
from bfemp.steppers.base import options_to_dict

__all__ = ["dumps", "levelset_dict", "motion_dict"]


def _uniform_or_rows(a: np.ndarray) -> list:
    """``a (n, d)`` as one row when every row is bitwise equal to the first, else all rows."""
    bits = np.ascontiguousarray(a).view(np.int64)
    if a.shape[0] and np.all(bits == bits[0]):
        return a[0].tolist()
    return a.tolist()


def material_dict(material: object) -> dict:
    """``{type, E, nu, density}`` of a material (``{type, K, G, density}`` for bulk_shear)."""
    if isinstance(material, BulkShearHyperelastic):
        return {"type": "bulk_shear", "K": material.K, "G": material.G, "density": material.density}
    kind = {NeoHookean: "neo_hookean", LinearElastic: "linear_elastic"}.get(type(material))
    if kind is None:
        raise SceneError(f"material of type {type(material).__name__} cannot be written to TOML")
    return {"type": kind, "E": material.E, "nu": material.nu, "density": material.density}


def motion_dict(motion: mo.Motion, where: str = "prescribed") -> dict:
    """The scene-file table of a prescribed motion."""
    if isinstance(motion, mo.Fixed):
        return {"type": "fixed"}
    if isinstance(motion, mo.Linear):
        return {"type": "linear", "velocity": list(motion.velocity)}
    if isinstance(motion, mo.Rotation):
        return {
            "type": "rotation",
            "center": list(motion.center),
            "angular_velocity": float(motion.angular_velocity),
            "axis": list(motion.axis),
        }
    if isinstance(motion, mo.Sequence):
        return {
            "type": "sequence",
            "segments": [
                {"duration": float(d), "motion": motion_dict(m, f"{where}.segments[{k}]")}
                for k, (d, m) in enumerate(motion.segments)
            ],
        }
    raise SceneError(
        f"motion of type {type(motion).__name__} cannot be written to TOML", field=where
    )


def levelset_dict(shape: object, where: str = "levelset") -> dict:
    """The scene-file table of a level set."""
    if isinstance(shape, ls.HalfPlane):
        return {"type": "half_plane", "point": list(shape.point), "normal": list(shape.unit_normal)}
    if isinstance(shape, ls.Box):
        return {"type": "box", "lower": list(shape.lower), "upper": list(shape.upper)}
    if isinstance(shape, ls.Disk):
        return {"type": "disk", "center": list(shape.center), "radius": float(shape.radius)}
    if isinstance(shape, ls.Union):
        parts = [levelset_dict(p, f"{where}.parts[{k}]") for k, p in enumerate(shape.parts)]
        return {"type": "union", "parts": parts}
    if isinstance(shape, ls.Inverted):
        return {"type": "inverted", "levelset": levelset_dict(shape.levelset, f"{where}.levelset")}
    raise SceneError(
        f"level set of type {type(shape).__name__} cannot be written to TOML", field=where
    )


class _Materials:
    """Named materials of the document; equal materials share one name."""

    def __init__(self, sources: dict) -> None:
        self.sources = sources
        self.tables: dict[str, dict] = {}
        self._names: dict[object, str] = {}

    def name(self, body: str, material: object) -> str:
        if material in self._names:
            return self._names[material]
        name = self.sources.get((body, "material")) or f"material{len(self.tables)}"
        while name in self.tables:
            name = f"{name}_"
        self.tables[name] = material_dict(material)
        self._names[material] = name
        return name


def _node_list(scene: object, spec: object, idx: np.ndarray) -> list[int]:
    """Node indices ``idx`` as written: in the file's numbering when the mesh is written as a
    file with points that no cell uses (node indices are read back in that numbering)."""
    mesh = scene._sources.get((spec.name, "mesh"))
    if spec.numbering is not None and isinstance(mesh, dict) and "file" in mesh:
        return spec.numbering.index[idx].tolist()
    return idx.tolist()


def _fem_dict(scene: object, spec: object, materials: _Materials) -> dict:
    sources = scene._sources
    out: dict = {"name": spec.name}
    mesh = sources.get((spec.name, "mesh"))
    if mesh is None:
        mesh = {"points": spec.mesh.points.tolist(), "cells": spec.mesh.cells.tolist()}
    out["mesh"] = mesh
    out["material"] = materials.name(spec.name, spec.material)
    if np.any(spec.velocity != 0.0):
        out["velocity"] = _uniform_or_rows(spec.velocity)
    if spec.motion is not None:
        out["prescribed"] = motion_dict(spec.motion)
        nodes = sources.get((spec.name, "prescribed_nodes"))
        if nodes is None and not spec.prescribed.all():
            nodes = _node_list(scene, spec, np.flatnonzero(spec.prescribed))
        if nodes is not None:
            out["prescribed_nodes"] = nodes
    return out


def _mpm_dict(scene: object, spec: object, materials: _Materials) -> dict:
    out: dict = {"name": spec.name}
    source = scene._sources.get((spec.name, "particles"))
    if source is None:
        out.update(particles=spec.x.tolist(), volumes=spec.volume.tolist())
    else:
        out["particles"] = source
    out["material"] = materials.name(spec.name, spec.material)
    if np.any(spec.velocity != 0.0):
        out["velocity"] = _uniform_or_rows(spec.velocity)
    return out


def dumps(
    scene: object,
    *,
    simulation: dict | None = None,
    run: dict | None = None,
    check: dict | None = None,
) -> str:
    """Scene-file TOML text of ``scene`` (a ``bfemp.Scene``) with optional ``[simulation]``,
    ``[run]``, ``[check]``."""
    doc: dict = {"scene": {"dim": scene.dim}}
    if np.any(scene.gravity != 0.0):
        doc["scene"]["gravity"] = scene.gravity.tolist()
    if simulation:
        doc["simulation"] = dict(simulation)
        options = doc["simulation"].get("options")
        if options is not None and not isinstance(options, dict):  # a StepperOptions
            doc["simulation"]["options"] = {
                k: v for k, v in options_to_dict(options).items() if v is not None
            }
    if run:
        doc["run"] = dict(run)
    materials = _Materials(scene._sources)
    fem = [_fem_dict(scene, spec, materials) for spec in scene._fem]
    mpm = [_mpm_dict(scene, spec, materials) for spec in scene._mpm]
    doc["materials"] = materials.tables
    if scene._grid is not None:
        doc["grid"] = {"dx": scene._grid.dx, "origin": list(scene._grid.origin)}
    contact = scene._contact
    if contact is not None:
        keys = ("dhat", "kappa", "mu", "eps_v", "friction_iterations")  # set_contact's arguments
        doc["contact"] = {key: getattr(contact, key) for key in keys}
        if scene._pair_mu:
            doc["contact"]["pairs"] = [
                {"bodies": [a, b], "mu": mu} for (a, b), mu in scene._pair_mu.items()
            ]
    boundaries = []
    for k, b in enumerate(scene._boundaries):
        boundary = {
            "kind": b.kind,
            "levelset": levelset_dict(b.levelset, f"boundary[{k}].levelset"),
        }
        if getattr(b, "motion", None) is not None:
            boundary["motion"] = motion_dict(b.motion, f"boundary[{k}].motion")
        boundaries.append(boundary)
    loads = []
    for body, idx, force in scene._loads:
        spec = scene._fem[body]
        load: dict = {"body": spec.name, "force": _uniform_or_rows(force)}
        if not np.array_equal(idx, np.arange(spec.mesh.n_points)):
            load["nodes"] = _node_list(scene, spec, idx)
        loads.append(load)
    for key, tables in (("fem", fem), ("mpm", mpm), ("boundary", boundaries), ("load", loads)):
        if tables:  # [[fem]], [[mpm]], [[boundary]], [[load]] after [contact], in this order
            doc[key] = tables
    if check:
        doc["check"] = dict(check)
    return dumps_toml(doc, header_comment="bfemp scene file (format: bfemp.scenefile)")
