"""The import direction of ARCHITECTURE.md: geometry and solvers import neither each other nor
bfemp; no import circle anywhere; the size limits of the library."""

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

FORBIDDEN = {
    "geometry": {"solvers", "bfemp", "benchmarks", "scipy", "sksparse"},
    "solvers": {"geometry", "bfemp", "benchmarks", "meshio", "fcl"},
    "bfemp": {"benchmarks"},
}


#: modules that must not import ``solvers.newton`` (ARCHITECTURE.md: the explicit grid strategies
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


def _read(tmp_path, source, reader=_imported_top_levels):
    """What ``reader`` finds imported by a module of text ``source``."""
    bad = tmp_path / "bad.py"
    bad.write_text(source)
    return reader(bad)


def test_layering_check_detects_a_violation(tmp_path):
    assert "solvers" in _read(tmp_path, "import numpy\nfrom solvers.newton import minimize\n")


def test_layering_check_sees_dynamic_imports(tmp_path):
    source = "import importlib\nm = importlib.import_module('benchmarks.tradeoff')\n"
    assert "benchmarks" in _read(tmp_path, source)
    assert "benchmarks" in _read(tmp_path, "m = __import__('benchmarks')\n")


@pytest.mark.parametrize("module", NO_NEWTON)
def test_explicit_strategies_never_import_newton(module):
    path = ROOT / module
    if not path.exists():  # the strategy is not written yet: nothing can break the rule
        assert module not in {str(p.relative_to(ROOT)) for p in ROOT.rglob("*.py")}
        return
    assert not any(m.startswith("solvers.newton") for m in _imported_modules(path)), module


def test_the_newton_rule_detects_a_violation(tmp_path):
    for source in ("from solvers.newton import minimize\n", "from solvers import newton\n"):
        assert "solvers.newton" in _read(tmp_path, source, _imported_modules)


#: every package of the repository the no-circle test covers
PACKAGES = ("benchmarks", "bfemp", "geometry", "solvers")


def _module_name(path: Path, root: Path) -> str:
    rel = path.relative_to(root).with_suffix("")
    return ".".join(rel.parts[:-1] if rel.name == "__init__" else rel.parts)


def _is_module(root: Path, parts: list[str]) -> bool:
    base = root / Path(*parts)
    return base.with_suffix(".py").exists() or (base / "__init__.py").exists()


def _import_graph(root: Path, packages: tuple[str, ...]) -> dict[str, set[str]]:
    """Module -> the modules of ``packages`` it imports (function-local imports included).

    An import names the longest dotted prefix that is a module under ``root``. A package's
    ``__init__`` is a facade: the edges from a package's own modules to the package itself are
    dropped, so a circle counts only through the modules the facade imports.
    """
    graph = {}
    for package in packages:
        for path in sorted((root / package).rglob("*.py")):
            name = _module_name(path, root)
            deps = set()
            for mod in _imported_modules(path):
                parts = mod.split(".")
                if parts[0] not in packages:
                    continue
                for k in range(len(parts), 0, -1):
                    if _is_module(root, parts[:k]):
                        cand = ".".join(parts[:k])
                        if cand != name and not name.startswith(cand + "."):
                            deps.add(cand)
                        break
            graph[name] = deps
    return graph


@pytest.mark.parametrize("package", PACKAGES)
def test_no_import_circle(package):
    """No module of ``package`` is on an import circle through any package of the repository."""
    graph = _import_graph(ROOT, PACKAGES)
    assert any(name.split(".")[0] == package for name in graph), f"no modules in {package}/"
    cycle = _find_cycle(graph, start=package)
    assert not cycle, f"import circle: {' -> '.join(cycle)}"


def test_the_circle_check_finds_a_hidden_circle(tmp_path):
    """Negative control: a loop hidden in a function-local import, across a package facade."""
    for rel, text in {
        "pkg/__init__.py": "from pkg.a import f\n",
        "pkg/a.py": "from pkg.b import g\n\ndef f():\n    return g()\n",
        "pkg/b.py": "def g():\n    from pkg.c import h\n    return h()\n",
        "pkg/c.py": "import numpy\nfrom pkg import a\n\ndef h():\n    return a\n",
        "other/__init__.py": "from pkg import f\n",
    }.items():
        (tmp_path / rel).parent.mkdir(exist_ok=True)
        (tmp_path / rel).write_text(text)
    graph = _import_graph(tmp_path, ("other", "pkg"))
    assert graph["other"] == {"pkg"}
    assert _find_cycle(graph) == ["pkg.a", "pkg.b", "pkg.c", "pkg.a"]
    (tmp_path / "pkg/c.py").write_text("def h():\n    return 1\n")  # the loop opened
    assert _find_cycle(_import_graph(tmp_path, ("other", "pkg"))) == []


def _find_cycle(graph: dict[str, set[str]], start: str = "") -> list[str]:
    """One import cycle of ``graph`` (module -> modules it imports) as a path, [] when none.

    ``start``: search only from the modules whose name begins with it (all by default).
    """
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
        if node.startswith(start) and state.get(node) is None:
            found = visit(node, [node])
            if found:
                return found
    return []


def test_cycle_finder_detects_a_circle():
    circle = {"scene": {"scenefile"}, "scenefile": {"simulation"}, "simulation": {"scene"}}
    assert _find_cycle(circle) == ["scene", "scenefile", "simulation", "scene"]
    assert _find_cycle({"a": {"b"}, "b": set()}) == []


# ----------------------------------------------------------------------- size of the house

#: the library packages held to the size limits
LIBRARY = ("bfemp", "geometry", "solvers")
MAX_FILE_LINES = 500
MAX_FUNCTION_LINES = 120


def _is_numba_kernel(node: ast.FunctionDef) -> bool:
    """Decorated with numba's ``njit``/``jit`` (bare, called, or as ``numba.njit``)."""
    for dec in node.decorator_list:
        target = dec.func if isinstance(dec, ast.Call) else dec
        name = target.attr if isinstance(target, ast.Attribute) else getattr(target, "id", "")
        if name in ("njit", "jit"):
            return True
    return False


def long_functions(path: Path, limit: int = MAX_FUNCTION_LINES) -> list[tuple[str, int, int]]:
    """``(qualified name, first line, length)`` of every function of ``path`` longer than
    ``limit`` lines (decorators excluded), numba kernels skipped."""
    found = []

    def visit(node: ast.AST, prefix: str) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.ClassDef):
                visit(child, f"{prefix}{child.name}.")
            elif isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef):
                length = child.end_lineno - child.lineno + 1
                if length > limit and not _is_numba_kernel(child):
                    found.append((f"{prefix}{child.name}", child.lineno, length))
                visit(child, f"{prefix}{child.name}.")

    visit(ast.parse(path.read_text(), filename=str(path)), "")
    return found


def library_files(root: Path = ROOT) -> list[Path]:
    return sorted(p for package in LIBRARY for p in (root / package).rglob("*.py"))


def test_no_library_file_over_the_line_limit():
    over = {
        str(p.relative_to(ROOT)): n
        for p in library_files()
        if (n := len(p.read_text().splitlines())) > MAX_FILE_LINES
    }
    assert not over, f"library files over {MAX_FILE_LINES} lines: {over}"


def test_no_library_function_over_the_line_limit():
    over = {
        f"{p.relative_to(ROOT)}:{line} {name}": n
        for p in library_files()
        for name, line, n in long_functions(p)
    }
    assert not over, f"functions over {MAX_FUNCTION_LINES} lines: {over}"


def test_the_function_limit_sees_methods_and_skips_numba_kernels(tmp_path):
    body = "".join(f"    x{i} = {i}\n" for i in range(130))
    src = tmp_path / "m.py"
    src.write_text(
        f"from numba import njit\n\nclass A:\n  def long(self):\n{body}\n"
        f"@njit(cache=True)\ndef kernel():\n{body}\ndef short():\n    return 1\n"
    )
    assert [(name, n) for name, _, n in long_functions(src)] == [("A.long", 131)]
