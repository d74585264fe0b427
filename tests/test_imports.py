"""The house rules on imports, read statically from the sources with :mod:`ast`.

Every ``import`` counts, also those inside functions or under ``TYPE_CHECKING`` (lazy imports
are still dependencies): the module graph has no cycle, and no package imports one above it in
the strict order of :data:`LAYERS`, without exception: the simulation (``sim``) below the judging
of its tables (``validation``), the files for other tools (``interop``), the facade (``pefsim``)
and, on top, the program (``cli``, a thin layer over ``pefsim``; ``docs/design.md`` §2).
"""

from __future__ import annotations

import ast
import itertools
from pathlib import Path

import networkx as nx

ROOT = Path(__file__).resolve().parents[1]
LAYERS = ("jit", "scenarios", "estimators", "planner", "sim", "validation", "interop", "pefsim", "cli")
"""The root packages, lowest first: a package may import only its own modules and those before it."""


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _modules() -> dict[str, Path]:
    found = {}
    for package in LAYERS:
        for path in sorted((ROOT / package).rglob("*.py")) if (ROOT / package).is_dir() else ():
            found[_module_name(path)] = path
    return found


def _resolve(name: str, modules: dict[str, Path]) -> str | None:
    """Return the project module ``name`` refers to (a module, or the package holding a name), else None."""
    while name:
        if name in modules:
            return name
        name = name.rpartition(".")[0]
    return None


def _imports(module: str, path: Path, modules: dict[str, Path]) -> set[str]:
    """Project modules ``module`` imports anywhere in its body (top level, functions, conditionals)."""
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    out = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), filename=str(path))):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join([*anchor, base] if base else anchor)
            # ``from pkg import mod`` imports the submodule pkg.mod when there is one
            names = [f"{base}.{a.name}" if f"{base}.{a.name}" in modules else base for a in node.names]
        else:
            continue
        for name in names:
            target = _resolve(name, modules)
            if target is not None and target != module:
                out.add(target)
    return out


def _graph() -> nx.DiGraph:
    modules = _modules()
    g = nx.DiGraph()
    g.add_nodes_from(modules)
    for module, path in modules.items():
        g.add_edges_from((module, target) for target in _imports(module, path, modules))
    return g


def _layer(module: str) -> int:
    """Index in :data:`LAYERS` of the root package holding ``module``."""
    return LAYERS.index(module.partition(".")[0])


def test_the_scan_sees_lazy_and_relative_imports():
    g = _graph()
    assert g.number_of_nodes() > 100
    assert g.has_edge("pefsim", "planner.placement.placement")  # inside a function
    assert g.has_edge("cli.map", "pefsim")


def test_no_import_cycle():
    g = _graph()
    cycles = [sorted(c) for c in itertools.islice(nx.simple_cycles(g), 10)]  # any length
    assert cycles == [], "import cycles: " + "; ".join(" <-> ".join(c) for c in cycles[:10])


def test_no_package_imports_a_higher_one():
    upward = sorted(f"{a} imports {b}" for a, b in _graph().edges if _layer(b) > _layer(a))
    assert upward == [], "\n".join(upward)


def test_a_negative_control_of_the_scan():
    g = _graph()
    g.add_edge("scenarios", "pefsim")  # what the rules forbid must be seen
    assert not nx.is_directed_acyclic_graph(g)
    assert _layer("pefsim") > _layer("scenarios") and _layer("cli.map") > _layer("pefsim") > _layer("validation.report")


CLI_REACHES = ("pefsim", "scenarios", "scenarios.errors", "jit.compiled")
"""What the program's modules may import besides each other: the facade, the error types
(``scenarios`` and ``scenarios.errors``) and the first-compilation notice; the work is the library's."""


def _past_the_facade(g: nx.DiGraph) -> dict[str, set[str]]:
    """Modules of ``cli`` -> what they import beyond :data:`CLI_REACHES` and ``cli`` itself."""
    program = [a for a in g if _layer(a) == LAYERS.index("cli")]
    past = {a: {b for b in g.successors(a) if b not in CLI_REACHES and _layer(b) != LAYERS.index("cli")}
            for a in program}
    return {a: bs for a, bs in past.items() if bs}


def test_the_program_calls_only_the_facade():
    past = _past_the_facade(_graph())
    assert not past, past


def test_a_negative_control_of_the_facade_rule():
    g = _graph()
    g.add_edge("cli.map", "planner.pef.map")  # what the rule forbids must be seen
    assert "planner.pef.map" in _past_the_facade(g)["cli.map"]


def test_every_installed_package_is_a_layer():
    """The packages a fresh install ships (pyproject's list) are exactly the layers scanned."""
    import tomllib

    find = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"]["find"]
    assert sorted(find["include"]) == sorted(f"{layer}*" for layer in LAYERS)
    roots = {p.parent.name for p in ROOT.glob("*/__init__.py")} - {"tests"}
    assert roots == set(LAYERS), roots ^ set(LAYERS)


def _test_module_imports(text: str) -> list[str]:
    """Names of test modules (``test_*``) that ``text`` imports from."""
    found = []
    for node in ast.walk(ast.parse(text)):
        names = ([node.module or ""] if isinstance(node, ast.ImportFrom)
                 else [a.name for a in node.names] if isinstance(node, ast.Import) else [])
        found += [n for n in names if n.split(".")[-1].startswith("test_")]
    return found


def test_test_modules_share_helpers_not_each_other():
    """Helpers shared by tests live in conftest.py or helper modules, never in another test module."""
    offenders = {str(p.relative_to(ROOT)): names for p in sorted((ROOT / "tests").rglob("test_*.py"))
                 if (names := _test_module_imports(p.read_text()))}
    assert not offenders, offenders
    assert _test_module_imports("from tests.sim.test_random_worlds import over_promise") == [
        "tests.sim.test_random_worlds"]  # the scan sees what it forbids


def test_no_benchmark_script_is_named_like_a_package():
    """No benchmark script is named like one of our packages.

    ``python benchmarks/NAME.py`` puts ``benchmarks/`` first on sys.path: a script named like one
    of our packages shadows it in every other script (``benchmarks/planner.py`` broke ``physics.py``).
    """
    bench = {p.stem for p in (ROOT / "benchmarks").glob("*.py")}
    packages = {p.parent.name for p in ROOT.glob("*/__init__.py")}
    assert {"planner", "sim", "scenarios"} <= packages
    assert not bench & packages, sorted(bench & packages)
