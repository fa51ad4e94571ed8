"""The import direction of DESIGN.md: geometry and solvers never import each other or bfemp."""

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

FORBIDDEN = {
    "geometry": {"solvers", "bfemp", "benchmarks", "scipy", "sksparse"},
    "solvers": {"geometry", "bfemp", "benchmarks", "meshio", "fcl"},
    "bfemp": {"benchmarks"},
}


#: modules that must not import ``solvers.newton`` (DESIGN.md: the explicit grid strategies
#: need no Newton; ``two_stage`` may call the physics-free ``minimize``)
NO_NEWTON = (
    "bfemp/steppers/augury.py",
    "bfemp/steppers/lr.py",
    "bfemp/contact/augury.py",
    "bfemp/contact/lr.py",
    "bfemp/steppers/explicit.py",
    "bfemp/steppers/single_field.py",
)

_DYNAMIC = {("importlib", "import_module"), ("builtins", "__import__"), (None, "__import__")}


def _dynamic_target(node: ast.Call) -> str | None:
    """The module named by ``importlib.import_module("x")`` / ``__import__("x")``, if literal."""
    func = node.func
    if isinstance(func, ast.Attribute) and isinstance(func.value, ast.Name):
        key = (func.value.id, func.attr)
    elif isinstance(func, ast.Name):
        key = (None, func.id)
    else:
        return None
    if key not in _DYNAMIC and key[1] != "import_module":
        return None
    if node.args and isinstance(node.args[0], ast.Constant) and isinstance(node.args[0].value, str):
        return node.args[0].value
    return None


def _imported_modules(path: Path) -> set[str]:
    """Dotted names of every module ``path`` imports, statically or by a literal dynamic call."""
    tree = ast.parse(path.read_text(), filename=str(path))
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names.add(node.module)
            names.update(f"{node.module}.{alias.name}" for alias in node.names)
        elif isinstance(node, ast.Call):
            target = _dynamic_target(node)
            if target:
                names.add(target)
    return names


def _imported_top_levels(path: Path) -> set[str]:
    return {name.split(".")[0] for name in _imported_modules(path)}


@pytest.mark.parametrize("package", sorted(FORBIDDEN))
def test_import_direction(package):
    files = sorted((ROOT / package).rglob("*.py"))
    assert files, f"no modules found in {package}/"
    offenders = {
        str(f.relative_to(ROOT)): sorted(_imported_top_levels(f) & FORBIDDEN[package])
        for f in files
    }
    offenders = {k: v for k, v in offenders.items() if v}
    assert not offenders, f"{package}/ imports across the layering: {offenders}"


def test_layering_check_detects_a_violation(tmp_path):
    bad = tmp_path / "bad.py"
    bad.write_text("import numpy\nfrom solvers.newton import minimize\n")
    assert "solvers" in _imported_top_levels(bad)


def test_layering_check_sees_dynamic_imports(tmp_path):
    bad = tmp_path / "bad.py"
    bad.write_text("import importlib\nm = importlib.import_module('benchmarks.tradeoff')\n")
    assert "benchmarks" in _imported_top_levels(bad)
    bad.write_text("m = __import__('benchmarks')\n")
    assert "benchmarks" in _imported_top_levels(bad)


@pytest.mark.parametrize("module", NO_NEWTON)
def test_explicit_strategies_never_import_newton(module):
    path = ROOT / module
    if not path.exists():  # the strategy is not written yet: nothing can break the rule
        assert module not in {str(p.relative_to(ROOT)) for p in ROOT.rglob("*.py")}
        return
    assert not any(m.startswith("solvers.newton") for m in _imported_modules(path)), module


def test_the_newton_rule_detects_a_violation(tmp_path):
    bad = tmp_path / "augury.py"
    bad.write_text("from solvers.newton import minimize\n")
    assert "solvers.newton" in _imported_modules(bad)
    bad.write_text("from solvers import newton\n")
    assert "solvers.newton" in _imported_modules(bad)


def test_no_import_circle_in_bfemp():
    """bfemp's modules import each other without a cycle (function-local imports included)."""
    graph = {}
    for path in sorted((ROOT / "bfemp").rglob("*.py")):
        rel = path.relative_to(ROOT).with_suffix("")
        name = ".".join(rel.parts[:-1] if rel.name == "__init__" else rel.parts)
        deps = set()
        for mod in _imported_modules(path):
            parts = mod.split(".")
            for k in range(len(parts), 0, -1):  # the longest prefix that is a bfemp module
                cand = ".".join(parts[:k])
                if (ROOT / Path(*parts[:k])).with_suffix(".py").exists() or (
                    ROOT / Path(*parts[:k]) / "__init__.py"
                ).exists():
                    if cand.startswith("bfemp") and cand != name:
                        deps.add(cand)
                    break
        graph[name] = deps
    # package __init__ re-exports are facades: an edge into a package counts only through
    # the modules the facade imports, so drop edges from a package's own modules to itself
    for name, deps in graph.items():
        graph[name] = {d for d in deps if not name.startswith(d + ".")}
    cycle = _find_cycle(graph)
    assert not cycle, f"import circle: {' -> '.join(cycle)}"


def _find_cycle(graph: dict[str, set[str]]) -> list[str]:
    """One import cycle of ``graph`` (module -> modules it imports) as a path, [] when none."""
    state: dict[str, int] = {}

    def visit(node: str, stack: list[str]) -> list[str]:
        state[node] = 1
        for dep in sorted(graph.get(node, ())):
            if state.get(dep) == 1:
                return [*stack[stack.index(dep) :], dep]
            if state.get(dep) is None:
                found = visit(dep, [*stack, dep])
                if found:
                    return found
        state[node] = 2
        return []

    for node in sorted(graph):
        if state.get(node) is None:
            found = visit(node, [node])
            if found:
                return found
    return []


def test_cycle_finder_detects_a_circle():
    circle = {"scene": {"scenefile"}, "scenefile": {"simulation"}, "simulation": {"scene"}}
    assert _find_cycle(circle) == ["scene", "scenefile", "simulation", "scene"]
    assert _find_cycle({"a": {"b"}, "b": set()}) == []
