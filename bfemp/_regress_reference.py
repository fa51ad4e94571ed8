"""The reference files of :mod:`bfemp.regress`: ``NAME.toml`` read into a :class:`Reference`
with its settings and tolerances (see :mod:`bfemp.regress` for the format and the defaults)."""

from __future__ import annotations

import os
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from bfemp.errors import SceneError
from bfemp.scenefile._fields import Table

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

__all__ = [
    "DEFAULT_QUANTITIES",
    "DEFAULT_TOLERANCES",
    "STATE_QUANTITIES",
    "Reference",
    "Tolerance",
    "default_reference_dir",
    "find_references",
    "load_reference",
    "tolerance_of",
]


STATE_QUANTITIES = ("fem_x", "fem_v", "mpm_x", "mpm_v", "mpm_F")
#: what a reference stores when its [regress] table names no quantities (those the scene has)
DEFAULT_QUANTITIES = (
    "fem_x",
    "fem_v",
    "mpm_x",
    "mpm_v",
    "energy_kinetic",
    "energy_elastic",
    "energy_total",
    "contact_pairs",
    "min_distance",
)


@dataclass(frozen=True)
class Tolerance:
    """Allowed deviation ``atol + rtol * scale`` (units of the quantity; rtol dimensionless)."""

    atol: float = 0.0
    rtol: float = 1e-8

    def allowed(self, scale: float) -> float:
        """The allowed max deviation for a quantity whose stored max magnitude is ``scale``."""
        return self.atol + self.rtol * scale


#: defaults per strategy (measured cross-thread drift <= 1.3e-14 relative, a 1 % change of a
#: stiffness or contact parameter >= 2e-5 relative: module docstring)
DEFAULT_TOLERANCES = {
    "explicit": Tolerance(atol=1e-12, rtol=1e-9),
    "barrier": Tolerance(atol=1e-12, rtol=1e-6),
    "two_stage": Tolerance(atol=1e-12, rtol=1e-6),
    # integer counts: a pair entering d-hat one step earlier is a change
    "contact_pairs": Tolerance(atol=0.5, rtol=0.0),
}
_EXPLICIT = ("single_field", "augury", "lr")


@dataclass(frozen=True)
class Reference:
    """A regression reference: a scene file with a ``[regress]`` table.

    Attributes:
        name: the file's stem.
        scene_file: the scene file (``NAME.toml``).
        steps: number of time steps run.
        every: store every ``every``-th step (step 0 and the last one always).
        quantities: names stored, or None for :data:`DEFAULT_QUANTITIES` the scene has.
        tolerances: per-quantity overrides of the strategy's defaults.
    """

    name: str
    scene_file: Path
    steps: int
    every: int
    quantities: tuple[str, ...] | None = None
    tolerances: dict[str, Tolerance] = field(default_factory=dict)

    @property
    def npz_path(self) -> Path:
        """The stored trajectory ``NAME.npz``."""
        return self.scene_file.with_suffix(".npz")

    @property
    def meta_path(self) -> Path:
        """The sidecar ``NAME.json``."""
        return self.scene_file.with_suffix(".json")

    def stored_steps(self) -> np.ndarray:
        """The step numbers stored, ``(n_stored,)`` int."""
        return np.unique(np.r_[np.arange(0, self.steps + 1, self.every), self.steps])


def _read_toml(path: Path) -> dict:
    """The TOML document of ``path``; ``SceneError`` naming the file when it cannot be read."""
    try:
        return tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as err:
        raise SceneError(f"cannot read: {err}", file=str(path)) from None


def load_reference(path: str | os.PathLike) -> Reference:
    """Read the ``[regress]`` table of the scene file ``path`` (the scene is read by the run)."""
    path = Path(path)
    if not path.is_file():
        raise SceneError(f"reference scene file not found: {path}")
    data = _read_toml(path).get("regress")
    if not isinstance(data, dict):
        raise SceneError(
            "missing table [regress]", file=str(path), hint="add [regress] with steps (and every)"
        )
    t = Table(data, file=str(path), path="regress")
    t.check_keys({"steps", "every", "quantities", "tolerances"}, required={"steps"})
    quantities = t.raw("quantities", None)
    if quantities is not None:
        if not (
            isinstance(quantities, list)
            and quantities
            and all(isinstance(q, str) for q in quantities)
        ):
            raise t.error(f"must be a non-empty list of names, got {quantities!r}", "quantities")
        quantities = tuple(quantities)
    tolerances = {}
    given = t.sub("tolerances", default_empty=True)
    for name in given.data:
        tol = given.sub(name)
        tol.check_keys({"atol", "rtol"})
        values = {key: tol.number(key, minimum=0.0) for key in tol.data}
        tolerances[name] = Tolerance(**{"atol": 0.0, "rtol": 0.0, **values})
    return Reference(
        name=path.stem,
        scene_file=path,
        steps=t.integer("steps", minimum=1),
        every=t.integer("every", default=1, minimum=1),
        quantities=quantities,
        tolerances=tolerances,
    )


def default_reference_dir() -> Path:
    """The checkout's ``references/`` folder (beside the ``bfemp`` package), the default of
    ``bfemp regress`` from whatever folder it is run."""
    return Path(__file__).resolve().parents[1] / "references"


def find_references(
    directory: str | os.PathLike, names: list[str] | None = None
) -> list[Reference]:
    """The references in ``directory`` (scene files with a ``[regress]`` table), by name.

    Raises ``ValueError`` naming the available references when a name is unknown.
    """
    directory = Path(directory)
    if not directory.is_dir():
        raise SceneError(f"reference folder not found: {directory}", hint="give --dir DIR")
    found = {  # other scene files in the folder are not references
        p.stem: p for p in sorted(directory.glob("*.toml")) if "regress" in _read_toml(p)
    }
    if not names:
        return [load_reference(p) for p in found.values()]
    unknown = [n for n in names if n not in found]
    if unknown:
        raise SceneError(
            f"unknown reference(s) {', '.join(unknown)} in {directory}; available: "
            f"{', '.join(found) or '(none)'}"
        )
    return [load_reference(found[n]) for n in names]


# ---------------------------------------------------------------------------------- running


def tolerance_of(ref: Reference, strategy: str, quantity: str) -> Tolerance:
    """The tolerance of ``quantity``: the reference's override, else the strategy's default."""
    if quantity in ref.tolerances:
        return ref.tolerances[quantity]
    if quantity == "contact_pairs":
        return DEFAULT_TOLERANCES["contact_pairs"]
    key = "explicit" if strategy in _EXPLICIT else strategy
    return DEFAULT_TOLERANCES.get(key, DEFAULT_TOLERANCES["barrier"])
