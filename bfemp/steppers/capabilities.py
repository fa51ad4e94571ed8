"""What each coupling strategy couples, and what it promises: declared in code, checked on scenes.

Every stepper class carries ``capabilities: ClassVar[Capabilities]``. ``Simulation`` calls
:func:`check_scene` before it builds a stepper:

- a pair of bodies the strategy does not couple (e.g. an MPM body and a FEM body under
  ``single_field``, which has no contact algorithm) is refused with a ``ValueError`` that names
  both bodies, the strategy and the strategies that do couple that kind of pair;
- a strategy whose contact needs ``scene.set_contact(...)`` (``barrier``, ``two_stage``) on a
  scene that has MPM and FEM bodies (or two FEM bodies) but no contact settings gets one warning
  naming the bodies: they would pass through each other;
- MPM bodies that share one background grid velocity field (every strategy but ``lr``) meet
  through it (MPM's native coupling): they cannot slide on each other where they share grid
  nodes (no slip, no friction law) and feel each other about a grid cell before they touch; one
  warning names them.

Pair kinds (:data:`PAIR_KINDS`), for two different bodies a and b:

- ``"mpm-mpm"``: two MPM bodies;
- ``"mpm-fem"``: an MPM body and a FEM body with at least one free node (deformable);
- ``"mpm-prescribed"``: an MPM body and a FEM body whose every node is scripted (a fixed plate,
  a moving indenter);
- ``"fem-fem"``: two FEM bodies, at least one of them with a free node.

Two fully scripted FEM bodies never interact in any strategy and are not a pair.

How a strategy couples a kind (:data:`COUPLINGS`): ``"contact"`` (the bodies meet at a contact
interface: they can separate, slide and, where the strategy has friction, stick) or ``"grid"``
(one shared grid velocity field: no slip where the bodies share grid nodes, and they part once
their stencils no longer overlap; measured in the conformance catalogue's MPM-MPM impacts,
restitution 0.8-0.9 at 1 m/s).

Penetration guarantee: ``Capabilities.penetration_bound_cells`` (0 for ``barrier`` and
``two_stage``: a step that would end inside a FEM body is a named failure; measured bounds in
each strategy's declaration). ``bfemp strategies`` prints :func:`strategy_table`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType

__all__ = [
    "BARRIER_PAIRS",
    "COUPLINGS",
    "PAIR_KINDS",
    "Capabilities",
    "check_scene",
    "pair_kind",
    "scene_pairs",
    "strategy_table",
]


#: the kinds of body pairs (module docstring)
PAIR_KINDS: tuple[str, ...] = ("mpm-mpm", "mpm-fem", "mpm-prescribed", "fem-fem")
#: how a strategy couples a pair kind (module docstring)
COUPLINGS: tuple[str, ...] = ("contact", "grid")

#: the pairs the barrier's collision sets couple (particles and FEM nodes against FEM boundary
#: facets, BFEMP eq. 27; never particle-particle: MPM bodies share the grid): ``barrier`` and
#: ``two_stage``, whose contact stage is the barrier's
BARRIER_PAIRS: dict[str, str] = {
    "mpm-mpm": "grid",
    "mpm-fem": "contact",
    "mpm-prescribed": "contact",
    "fem-fem": "contact",
}

_KIND_TEXT = {
    "mpm-mpm": "MPM-MPM",
    "mpm-fem": "MPM-deformable FEM",
    "mpm-prescribed": "MPM-prescribed FEM",
    "fem-fem": "FEM-FEM",
}


@dataclass(frozen=True)
class Capabilities:
    """What one strategy couples and guarantees.

    Attributes:
        pairs: pair kind -> coupling (``"contact"`` or ``"grid"``); a kind not listed is not
            coupled: a scene with such a pair is refused.
        needs_contact_settings: whether the contact pairs act only with
            ``scene.set_contact(...)`` (the barrier's d-hat and kappa).
        penetration_bound_cells: 0.0 when no particle or FEM node ever ends inside another FEM
            body (a step that would is a named failure); else the deepest penetration stated, in
            grid cells (dx of the MPM grid, or of the strategy's contact grid); None when the
            strategy couples nothing with a FEM body.
        penetration_note: how the bound was obtained, or why there is none.
        friction: whether contact can carry Coulomb friction (``scene.set_contact(mu=...)``).
        inversion_free: whether every FEM cell and particle keeps J > 0 (a step that would
            invert is refused by the line search, not taken).
        needs_mpm_body: whether the strategy runs only scenes with an MPM body (``lr``: its
            materials live on the MPM grid; FEM bodies join through their boundary nodes).
    """

    pairs: Mapping[str, str]
    needs_contact_settings: bool
    penetration_bound_cells: float | None
    penetration_note: str
    friction: bool = True
    inversion_free: bool = False
    needs_mpm_body: bool = False

    def __post_init__(self) -> None:
        for kind, how in self.pairs.items():
            if kind not in PAIR_KINDS:
                raise ValueError(f"Capabilities.pairs: unknown pair kind {kind!r} ({PAIR_KINDS})")
            if how not in COUPLINGS:
                raise ValueError(f"Capabilities.pairs[{kind!r}] must be one of {COUPLINGS}")
        object.__setattr__(self, "pairs", MappingProxyType(dict(self.pairs)))

    def couples(self, kind: str) -> str | None:
        """How this strategy couples ``kind`` (``"contact"``, ``"grid"``), None if not at all."""
        return self.pairs.get(kind)


def pair_kind(a_is_mpm: bool, b_is_mpm: bool, a_fixed: bool, b_fixed: bool) -> str | None:
    """The kind of a pair of bodies (None for two fully scripted FEM bodies: never a pair)."""
    if a_is_mpm and b_is_mpm:
        return "mpm-mpm"
    if a_is_mpm or b_is_mpm:
        fixed = b_fixed if a_is_mpm else a_fixed
        return "mpm-prescribed" if fixed else "mpm-fem"
    if a_fixed and b_fixed:
        return None
    return "fem-fem"


def scene_pairs(model: object) -> list[tuple[str, str, str]]:
    """Every pair of bodies of ``model`` that may meet: ``(kind, name a, name b)``.

    FEM bodies come first, in insertion order, then MPM bodies (``bfemp.diagnostics`` order).
    """
    bodies = [(b.name, False, bool(model.fem_prescribed[b.nodes].all())) for b in model.fem_bodies]
    bodies += [(b.name, True, False) for b in model.mpm_bodies]
    out = []
    for i, (name_a, mpm_a, fixed_a) in enumerate(bodies):
        for name_b, mpm_b, fixed_b in bodies[i + 1 :]:
            kind = pair_kind(mpm_a, mpm_b, fixed_a, fixed_b)
            if kind is not None:
                out.append((kind, name_a, name_b))
    return out


def check_scene(
    model: object, strategy: str, registry: Mapping[str, type], *, allow_uncoupled: bool = False
) -> list[str]:
    """Refuse the pairs ``strategy`` does not couple; return the warnings the scene deserves.

    Args:
        model: the ``bfemp.Model``.
        strategy: the strategy's registry name.
        registry: name -> stepper class (``bfemp.steppers.STRATEGIES``).
        allow_uncoupled: turn the refusal of uncoupled pairs into a warning (for a scene whose
            bodies are known never to meet, or to show what happens without coupling).

    Returns:
        the warning messages (``NAME: text``); ``Simulation`` issues them
        (:func:`bfemp.errors.warn_user`: logged, warned, kept in ``diagnostics``).

    Raises:
        ValueError: a pair the strategy does not couple, naming both bodies, the strategy and
            the strategies that would serve.
    """
    caps: Capabilities = registry[strategy].capabilities
    if caps.needs_mpm_body and not model.mpm_bodies:
        serving = [n for n, c in registry.items() if not c.capabilities.needs_mpm_body]
        raise ValueError(
            f"strategy {strategy!r} runs only scenes with an MPM body (its bodies meet on the MPM "
            f"grid) and this scene has none; for FEM bodies alone use one of "
            f"{', '.join(repr(n) for n in serving)}"
        )
    pairs = scene_pairs(model)
    warnings: list[str] = []
    for kind, a, b in pairs:
        if caps.couples(kind) is None:
            # the strategies that couple the kind through contact, else through the grid
            how = {n: c.capabilities.couples(kind) for n, c in registry.items()}
            couplers = [n for n, h in how.items() if h == "contact"] or [n for n in how if how[n]]
            serving = ", ".join(repr(n) for n in couplers) or "none"
            message = (
                f"strategy {strategy!r} does not couple bodies {a!r} and {b!r} "
                f"({_KIND_TEXT[kind]}): they would pass through each other; strategies that "
                f"couple {_KIND_TEXT[kind]} pairs: {serving} (`bfemp strategies` lists what each "
                "couples)"
            )
            if not allow_uncoupled:
                raise ValueError(message + "; Simulation(..., allow_uncoupled=True) runs it anyway")
            warnings.append("UNCOUPLED: " + message)
    contact_pairs = [(a, b) for kind, a, b in pairs if caps.couples(kind) == "contact"]
    if caps.needs_contact_settings and model.contact is None and contact_pairs:
        names = ", ".join(f"{a!r} and {b!r}" for a, b in contact_pairs)
        warnings.append(
            f"NO_CONTACT: bodies {names} share the scene without contact settings: under "
            f"{strategy!r} they pass through each other; call scene.set_contact(dhat=..., "
            "kappa=...) (scene file: [contact]) to make them meet"
        )
    grid_pairs = [(a, b) for kind, a, b in pairs if caps.couples(kind) == "grid"]
    if grid_pairs:
        names = ", ".join(f"{a!r} and {b!r}" for a, b in grid_pairs)
        warnings.append(
            f"GRID_COUPLED: MPM bodies {names} share one grid velocity field under {strategy!r}: "
            "where they share grid nodes they cannot slide on each other (no slip, no friction "
            "law) and they feel each other about a grid cell before touching (strategy 'lr' "
            "gives each body its own field and a contact law)"
        )
    return warnings


def strategy_table(registry: Mapping[str, type]) -> str:
    """A text table: per strategy, how it couples each pair kind, friction and the guarantees."""
    header = ["strategy", *(_KIND_TEXT[k] for k in PAIR_KINDS), "friction", "penetration"]
    header.append("needs")
    rows = [header]
    for name, cls in registry.items():
        caps: Capabilities = cls.capabilities
        bound = caps.penetration_bound_cells
        if bound is None:
            pen = "-"
        elif bound == 0.0:
            pen = "none (named failure)"
        else:
            pen = f"<= {bound:g} cells"
        rows.append(
            [name, *(caps.couples(k) or "refused" for k in PAIR_KINDS)]
            + ["yes" if caps.friction else "no", pen]
            + ["an MPM body" if caps.needs_mpm_body else "-"]
        )
    widths = [max(len(r[i]) for r in rows) for i in range(len(header))]
    lines = ["  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)).rstrip() for r in rows]
    lines.insert(1, "  ".join("-" * w for w in widths))
    notes = [f"{name}: {cls.capabilities.penetration_note}" for name, cls in registry.items()]
    return "\n".join(lines + ["", "penetration:"] + ["  " + n for n in notes])
