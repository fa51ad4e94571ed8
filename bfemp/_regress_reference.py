"""The reference files of :mod:`bfemp.regress`: ``NAME.toml`` read into a :class:`Reference`
with its settings and tolerances (see :mod:`bfemp.regress` for the format and the defaults)."""

from __future__ import annotations

import os
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from bfemp.errors import SceneError

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


def _default_tolerance(strategy: str, quantity: str) -> Tolerance:
    if quantity == "contact_pairs":
        return DEFAULT_TOLERANCES["contact_pairs"]
    key = "explicit" if strategy in _EXPLICIT else strategy
    return DEFAULT_TOLERANCES.get(key, DEFAULT_TOLERANCES["barrier"])


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


def _positive_int(t: dict, key: str, file: str, default: int | None = None) -> int:
    value = t.get(key, default)
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise SceneError(
            f"must be a positive integer, got {value!r}", file=file, field=f"regress.{key}"
        )
    return value


def load_reference(path: str | os.PathLike) -> Reference:
    """Read the ``[regress]`` table of the scene file ``path`` (the scene is read by the run)."""
    path = Path(path)
    file = str(path)
    if not path.is_file():
        raise SceneError(f"reference scene file not found: {path}")
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as err:
        raise SceneError(f"cannot read the reference: {err}", file=file) from None
    t = data.get("regress")
    if not isinstance(t, dict):
        raise SceneError(
            "missing table [regress]", file=file, hint="add [regress] with steps (and every)"
        )
    unknown = set(t) - {"steps", "every", "quantities", "tolerances"}
    if unknown:
        raise SceneError(
            f"unknown key(s) {sorted(unknown)}; known: steps, every, quantities, tolerances",
            file=file,
            field="regress",
        )
    steps = _positive_int(t, "steps", file)
    every = _positive_int(t, "every", file, default=1)
    quantities = t.get("quantities")
    if quantities is not None:
        if not (
            isinstance(quantities, list)
            and quantities
            and all(isinstance(q, str) for q in quantities)
        ):
            raise SceneError(
                f"must be a non-empty list of names, got {quantities!r}",
                file=file,
                field="regress.quantities",
            )
        quantities = tuple(quantities)
    tolerances = {}
    for name, tol in t.get("tolerances", {}).items():
        where = f"regress.tolerances.{name}"
        if not isinstance(tol, dict) or set(tol) - {"atol", "rtol"}:
            raise SceneError(f"must be a table {{atol, rtol}}, got {tol!r}", file=file, field=where)
        values = {}
        for key, value in tol.items():
            if isinstance(value, bool) or not isinstance(value, int | float) or not value >= 0:
                raise SceneError(
                    f"must be a number >= 0, got {value!r}", file=file, field=f"{where}.{key}"
                )
            values[key] = float(value)
        tolerances[name] = Tolerance(**{"atol": 0.0, "rtol": 0.0, **values})
    return Reference(
        name=path.stem,
        scene_file=path,
        steps=steps,
        every=every,
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
    found = {}
    for path in sorted(directory.glob("*.toml")):
        try:
            data = tomllib.loads(path.read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as err:
            raise SceneError(f"cannot read: {err}", file=str(path)) from None
        if "regress" in data:  # other scene files in the folder are not references
            found[path.stem] = path
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
    return ref.tolerances.get(quantity, _default_tolerance(strategy, quantity))
