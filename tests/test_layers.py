"""The package's layers, bottom to top: utils -> rl -> environments -> motion -> experts -> datasets -> algorithms ->
experiment -> evaluation -> benchmark. A module's module-level imports stay in its layer or point down (the package root
and `loco_il.rollout` may import anything), they form no cycle, and every subpackage imports on its own in
a fresh interpreter.

Only module-level imports count (not those inside functions or under ``if TYPE_CHECKING:``): an import
inside a function runs when the function is called, after every module has loaded.
"""
from __future__ import annotations

import ast
import os
import subprocess
import sys
from collections import defaultdict
from pathlib import Path

import pytest

import loco_il

LAYERS = ("utils", "rl", "environments", "motion", "experts", "datasets", "algorithms", "experiment", "evaluation", "benchmark")
#: modules above every layer: the package root (re-exports the environments) and the rollout command
TOP = {"loco_il", "loco_il.rollout"}
#: upward imports that are known and not fixed yet: (importer, imported) -> why it is still there. A fixed one
#: must leave this list (the test fails on a stale entry, so the list stays true).
KNOWN_UPWARD: dict[tuple[str, str], str] = {}

ROOT = Path(loco_il.__file__).resolve().parent


def _modules() -> dict[str, Path]:
    """Module name -> file of every module of the package (a package is its ``__init__.py``)."""
    out = {}
    for path in ROOT.rglob("*.py"):
        parts = list(path.relative_to(ROOT.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


MODULES = _modules()


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or \
        (isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


def _module_level_imports(body: list[ast.stmt]) -> list[ast.Import | ast.ImportFrom]:
    """Import statements that run when the module is imported: not in functions, not under TYPE_CHECKING."""
    found: list[ast.Import | ast.ImportFrom] = []
    for node in body:
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            found.append(node)
        elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            continue
        elif isinstance(node, ast.If) and _is_type_checking(node.test):
            found.extend(_module_level_imports(node.orelse))
        else:
            for field in ("body", "orelse", "finalbody", "handlers", "cases"):
                for child in getattr(node, field, None) or []:
                    found.extend(_module_level_imports(getattr(child, "body", None) or [child])
                                 if isinstance(child, (ast.ExceptHandler, ast.match_case)) else
                                 _module_level_imports([child]))
    return found


def _resolve(name: str) -> str | None:
    """The longest module of the package that ``name`` names (``a.b.func`` -> ``a.b``), or None."""
    while name and name not in MODULES:
        name = name.rpartition(".")[0]
    return name or None


def _imported(module: str, node: ast.Import | ast.ImportFrom) -> set[str]:
    if isinstance(node, ast.Import):
        return {m for a in node.names if (m := _resolve(a.name))}
    base = node.module or ""
    if node.level:
        package = module if MODULES[module].name == "__init__.py" else module.rpartition(".")[0]
        for _ in range(node.level - 1):
            package = package.rpartition(".")[0]
        base = f"{package}.{base}" if base else package
    return {m for a in node.names if (m := _resolve(f"{base}.{a.name}"))}


def _ancestors(module: str) -> list[str]:
    parts = module.split(".")
    return [".".join(parts[:i]) for i in range(2, len(parts))]


def import_graph() -> tuple[dict[str, set[str]], dict[str, set[str]]]:
    """(explicit, executed): the modules each module imports at module level, and those the imports run (also
    the ``__init__`` of every package entered on the way, except the importer's own packages). The package
    root, which every import runs first, is left out."""
    explicit: dict[str, set[str]] = {}
    executed: dict[str, set[str]] = defaultdict(set)
    for module, path in MODULES.items():
        targets = set()
        for node in _module_level_imports(ast.parse(path.read_text(encoding="utf-8")).body):
            targets |= _imported(module, node)
        targets.discard("loco_il")
        targets.discard(module)
        explicit[module] = targets
        own = set(_ancestors(module)) | {module}
        for target in targets:
            executed[module] |= ({target} | set(_ancestors(target))) - own
    return explicit, executed


def layer(module: str) -> int | None:
    """Index of the module's layer in `LAYERS`; None for `TOP` modules."""
    if module in TOP:
        return None
    return LAYERS.index(module.split(".")[1])


def upward_imports(explicit: dict[str, set[str]]) -> set[tuple[str, str]]:
    out = set()
    for module, targets in explicit.items():
        if layer(module) is None:
            continue
        out |= {(module, t) for t in targets if layer(t) is not None and layer(t) > layer(module)}
    return out


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan's algorithm, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found = []
    for start in sorted(graph):
        if start in index:
            continue
        work = [(start, iter(sorted(graph.get(start, ()))))]
        index[start] = low[start] = len(index)
        stack.append(start)
        on_stack.add(start)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = len(index)
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph.get(child, ())))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                if len(component) > 1:
                    found.append(sorted(component))
    return found


def test_every_module_belongs_to_a_layer():
    unknown = sorted(m for m in MODULES if m not in TOP and m.split(".")[1] not in LAYERS)
    assert not unknown, f"modules outside the layers {LAYERS}: {unknown}; add their package to LAYERS or TOP"


def test_no_import_cycles():
    _, executed = import_graph()
    found = cycles(executed)
    assert not found, "module-level import cycles:\n" + "\n".join(" <-> ".join(c) for c in found)


def test_imports_point_down_the_layers():
    explicit, _ = import_graph()
    found = upward_imports(explicit)
    new = sorted(found - set(KNOWN_UPWARD))
    fixed = sorted(set(KNOWN_UPWARD) - found)
    lines = [f"  {a} (layer {a.split('.')[1]}) imports {b} (layer {b.split('.')[1]})" for a, b in new]
    assert not new, ("upward imports (layers, bottom to top: " + " -> ".join(LAYERS) + "):\n" + "\n".join(lines)
                     + "\nimport inside the function that needs it, or move the code down")
    assert not fixed, f"no longer imported upward, remove from KNOWN_UPWARD: {fixed}"


def test_the_graph_sees_known_imports():
    """The parser finds what it should: a module-level import, a relative one, one under TYPE_CHECKING and one
    in a function."""
    explicit, executed = import_graph()
    assert "loco_il.environments.registry" in explicit["loco_il.datasets.trajectory"]
    assert "loco_il.motion.mocap.skeleton" in explicit["loco_il.motion.mocap.bvh"]              # from .skeleton
    assert "loco_il.datasets" not in explicit["loco_il.environments.base"]                      # in a method
    assert "loco_il.motion.mocap" in executed["loco_il.datasets.real"]                          # package __init__
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    tree = ast.parse("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    import x\nelse:\n    import y\n"
                     "def f():\n    import z\ntry:\n    import w\nexcept ImportError:\n    import v\n")
    names = {a.name for node in _module_level_imports(tree.body) for a in node.names}
    assert names == {"TYPE_CHECKING", "y", "w", "v"}


SUBPACKAGES = sorted(m for m, p in MODULES.items() if p.name == "__init__.py" and m != "loco_il")


def test_every_subpackage_imports_alone():
    """Each subpackage in its own fresh interpreter, as many at a time as there are cores (each costs seconds)."""
    from concurrent.futures import ThreadPoolExecutor
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT.parent), os.environ.get("PYTHONPATH", "")])}

    def import_alone(package: str) -> str | None:
        out = subprocess.run([sys.executable, "-c", f"import {package}"], cwd=ROOT.parent, env=env,
                             capture_output=True, text=True, timeout=300)
        return None if out.returncode == 0 else f"`import {package}` failed:\n{out.stderr[-1500:]}"

    with ThreadPoolExecutor(max_workers=os.cpu_count() or 1) as pool:
        failures = [f for f in pool.map(import_alone, SUBPACKAGES) if f]
    assert len(SUBPACKAGES) > 10 and not failures, "\n".join(failures)
