"""The top-level API is regular: every strategy's options and every integrator are exported."""

import bfemp
import bfemp.steppers
from bfemp.integrators import INTEGRATOR_NAMES, integrator_from_name


def _sorted_like_ruff(names: list[str]) -> list[str]:
    """ruff's RUF022 order: SCREAMING_CASE, then CamelCase, then the rest, each alphabetical."""

    def key(name: str) -> tuple[int, str]:
        kind = 0 if name.isupper() else 1 if name[:1].isupper() else 2
        return kind, name

    return sorted(names, key=key)


def test_every_strategy_exports_its_options():
    for name, cls in bfemp.STRATEGIES.items():
        options = cls.Options
        assert options.__name__ in bfemp.__all__, f"{name}: {options.__name__} not exported"
        assert getattr(bfemp, options.__name__) is options


def test_every_integrator_is_exported_under_its_constant_name():
    for name in INTEGRATOR_NAMES:
        constant = name.upper()
        assert constant in bfemp.__all__, f"integrator {name!r}: bfemp.{constant} not exported"
        assert getattr(bfemp, constant) is integrator_from_name(name)


def test_exports_resolve_and_are_sorted():
    for module in (bfemp, bfemp.steppers):
        assert all(hasattr(module, n) for n in module.__all__), module.__name__
        assert module.__all__ == _sorted_like_ruff(module.__all__), module.__name__
        assert len(set(module.__all__)) == len(module.__all__)
    assert not hasattr(bfemp.steppers, "ImplicitStepper")
