"""The dependency rule between our packages, read from the source with `ast` (nothing is imported).

In: every .py file of rh_common, rh_dataset, rh_eval, rana and rh_demo. Out: pass, or a failure naming each
offending `file:line` and the edge. Four checks on the packages:
  * allowed edges: rh_common imports no other package of ours; rh_dataset and rh_eval import only rh_common;
    rana imports rh_common (and nothing of rh_dataset or rh_eval); rh_demo may import every package.
    Module-level and function-level imports both count: a lazy import is still a dependency.
  * nothing private across packages: no module imports a `_name` module or a `_name` from another package.
  * no import cycle between modules at import time (module-level imports only; an import inside a function runs
    after both modules have loaded, and `if TYPE_CHECKING:` blocks never run).
  * no cycle between the parts of a package (its subpackages and top modules), lazy imports included.
And every import of one of our modules (packages, tests, bench) names a module or name that exists.
Why a test and not a convention: the seams cost more than they saved once rana reached into the generator for the
body model and into the evaluator for its weights (issue #14); this keeps the graph from growing back.
"""
from __future__ import annotations

import ast
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("rh_common", "rh_dataset", "rh_eval", "rana", "rh_demo")

# package -> the packages of ours it may import (besides itself)
ALLOWED = {
    "rh_common": set(),
    "rh_dataset": {"rh_common"},
    "rh_eval": {"rh_common"},
    "rana": {"rh_common"},
    "rh_demo": {"rh_common", "rh_dataset", "rh_eval", "rana"},
}


@dataclass(frozen=True)
class Edge:
    src: str  # importing module, dotted
    dst: str  # imported module, dotted (the longest prefix that is one of our modules)
    names: tuple[str, ...]  # names taken from dst by `from dst import a, b` (empty for `import dst`)
    file: str  # path relative to the repository
    line: int
    top_level: bool  # runs when `src` is imported (not inside a function, not under TYPE_CHECKING)

    def where(self) -> str:
        return f"{self.file}:{self.line}"


def _modules() -> dict[str, Path]:
    """dotted module name -> file, for every module of our packages (a package is its __init__.py)."""
    out = {}
    for pkg in PACKAGES:
        for path in sorted((ROOT / pkg).rglob("*.py")):
            parts = list(path.relative_to(ROOT).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            out[".".join(parts)] = path
    return out


MODULES = _modules()


def _is_package(module: str) -> bool:
    return MODULES[module].name == "__init__.py"


def _resolve(module: str, node: ast.ImportFrom) -> str:
    """The absolute module an ImportFrom names (relative imports resolved against `module`)."""
    if node.level == 0:
        return node.module or ""
    base = module.split(".")
    if not _is_package(module):
        base = base[:-1]  # a plain module's `.` is its package
    base = base[: len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def _ours(dotted: str) -> str | None:
    """The longest prefix of `dotted` that is one of our modules (None for third-party and stdlib)."""
    parts = dotted.split(".")
    for n in range(len(parts), 0, -1):
        cand = ".".join(parts[:n])
        if cand in MODULES:
            return cand
    return None


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


def _walk(node: ast.AST, top_level: bool):
    """(import node, runs at import time) for every import under `node`."""
    for child in ast.iter_child_nodes(node):
        if isinstance(child, (ast.Import, ast.ImportFrom)):
            yield child, top_level
        elif isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
            yield from _walk(child, False)
        elif isinstance(child, ast.If) and _is_type_checking(child.test):
            for stmt in child.body:
                yield from _walk(ast.Module(body=[stmt], type_ignores=[]), False)
            for stmt in child.orelse:
                yield from _walk(ast.Module(body=[stmt], type_ignores=[]), top_level)
        else:
            yield from _walk(child, top_level)


def _edges_of(module: str, path: Path) -> list[Edge]:
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    rel = str(path.relative_to(ROOT))
    edges = []
    for node, top in _walk(tree, True):
        if isinstance(node, ast.Import):
            for alias in node.names:
                dst = _ours(alias.name)
                if dst:
                    edges.append(Edge(module, dst, (), rel, node.lineno, top))
            continue
        target = _resolve(module, node)
        dst = _ours(target)
        if dst is None:
            continue
        names = tuple(a.name for a in node.names)
        if dst == target:
            # `from pkg import sub` may name submodules: each is an edge to that submodule.
            subs = [n for n in names if f"{dst}.{n}" in MODULES]
            plain = tuple(n for n in names if f"{dst}.{n}" not in MODULES)
            for n in subs:
                edges.append(Edge(module, f"{dst}.{n}", (), rel, node.lineno, top))
            if plain or not subs:
                edges.append(Edge(module, dst, plain, rel, node.lineno, top))
        else:
            edges.append(Edge(module, dst, names, rel, node.lineno, top))
    return edges


EDGES = [e for m, p in MODULES.items() for e in _edges_of(m, p)]


def _pkg(module: str) -> str:
    return module.split(".")[0]


def test_every_package_is_seen():
    # guards the walk itself: a broken glob would make every other test pass vacuously
    assert {_pkg(m) for m in MODULES} == set(PACKAGES)
    assert any(e.src.startswith("rh_dataset.") and e.dst.startswith("rh_common") for e in EDGES)


def test_imports_stay_inside_the_allowed_package_graph():
    bad = [f"{e.where()}: {e.src} -> {e.dst} ({_pkg(e.src)} may import {sorted(ALLOWED[_pkg(e.src)]) or 'none of ours'})"
           for e in EDGES if _pkg(e.dst) != _pkg(e.src) and _pkg(e.dst) not in ALLOWED[_pkg(e.src)]]
    if bad:
        pytest.fail("imports outside the allowed package graph:\n  " + "\n  ".join(bad), pytrace=False)


def test_no_private_module_or_name_across_packages():
    bad = []
    for e in EDGES:
        if _pkg(e.dst) == _pkg(e.src):
            continue
        private_parts = [p for p in e.dst.split(".") if p.startswith("_") and p != "__init__"]
        if private_parts:
            bad.append(f"{e.where()}: {e.src} -> {e.dst} (private module {private_parts[0]})")
        for n in e.names:
            if n.startswith("_"):
                bad.append(f"{e.where()}: {e.src} imports private name {n} from {e.dst}")
    if bad:
        pytest.fail("private names imported across packages:\n  " + "\n  ".join(bad), pytrace=False)


def _bound_names(module: str) -> set[str]:
    """Every name `module` binds anywhere (defs, classes, assignments, imports): a lenient 'does it exist'."""
    out: set[str] = set()
    for n in ast.walk(ast.parse(MODULES[module].read_text(encoding="utf-8"))):
        if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            out.add(n.name)
        elif isinstance(n, (ast.Assign, ast.AnnAssign, ast.AugAssign)):
            for t in (n.targets if isinstance(n, ast.Assign) else [n.target]):
                out.update(x.id for x in ast.walk(t) if isinstance(x, ast.Name))
        elif isinstance(n, (ast.Import, ast.ImportFrom)):
            out.update((a.asname or a.name).split(".")[0] for a in n.names)
    return out


def test_every_import_of_ours_resolves():
    """Each import of one of our modules, in the packages, tests and bench, names a module or name that exists.
    Why: with the editable install, a module moved away in a working copy is still found in the installed
    checkout, so a stale import would pass there and fail in a clean one."""
    bound: dict[str, set[str]] = {}
    bad = []
    files = [p for d in PACKAGES + ("tests", "bench") for p in sorted((ROOT / d).rglob("*.py"))]
    for path in files:
        parts = list(path.relative_to(ROOT).with_suffix("").parts)
        me = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            where = f"{path.relative_to(ROOT)}:{getattr(node, 'lineno', 0)}"
            if isinstance(node, ast.Import):
                bad += [f"{where}: import {a.name} (no such module)" for a in node.names
                        if a.name.split(".")[0] in PACKAGES and a.name not in MODULES]
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    base = me.split(".") if path.name == "__init__.py" else me.split(".")[:-1]
                    base = base[: len(base) - (node.level - 1)]
                    target = ".".join(base + ([node.module] if node.module else []))
                else:
                    target = node.module or ""
                if target.split(".")[0] not in PACKAGES:
                    continue
                if target not in MODULES:
                    bad.append(f"{where}: from {target} import ... (no such module)")
                    continue
                names = bound.setdefault(target, _bound_names(target))
                bad += [f"{where}: from {target} import {a.name} (not there)" for a in node.names
                        if a.name != "*" and a.name not in names and f"{target}.{a.name}" not in MODULES]
    if bad:
        pytest.fail("imports of our modules that do not resolve:\n  " + "\n  ".join(bad), pytrace=False)


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (or a self-loop), by Tarjan's algorithm."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    out: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1 or v in graph.get(v, ()):
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def _ancestors(module: str) -> list[str]:
    parts = module.split(".")
    return [".".join(parts[:n]) for n in range(1, len(parts))]


def _loads(e: Edge) -> list[str]:
    """The modules an import runs: importing `a.b.c` first runs `a/__init__.py` and `a/b/__init__.py`, except
    the importer's own packages (already being loaded when it runs)."""
    own = set(_ancestors(e.src)) | {e.src}
    return [m for m in _ancestors(e.dst) + [e.dst] if m not in own]


def _import_time_graph() -> dict[str, set[str]]:
    graph: dict[str, set[str]] = {m: set() for m in MODULES}
    for e in EDGES:
        if e.top_level:
            graph[e.src].update(_loads(e))
    return graph


def _unit(module: str) -> str:
    """A package's direct part: `rh_dataset.poses.rig` -> `rh_dataset.poses`, `rh_dataset.cli` itself."""
    return ".".join(module.split(".")[:2])


def test_no_import_cycle_at_import_time():
    graph = _import_time_graph()
    lines = []
    for comp in _cycles(graph):
        members = set(comp)
        lines.append(" <-> ".join(comp))
        for e in EDGES:
            if e.top_level and e.src in members and members & set(_loads(e)):
                lines.append(f"    {e.where()}: {e.src} -> {e.dst}")
    if lines:
        pytest.fail("import cycles (module-level imports):\n  " + "\n  ".join(lines), pytrace=False)


def test_no_cycle_between_parts_of_a_package():
    """The direct parts of a package (subpackages and top modules) form no cycle, lazy imports included: a
    function-level import hides a cycle from Python, not from the reader (characters <-> poses, issue #14)."""
    graph: dict[str, set[str]] = {}
    for e in EDGES:
        a, b = _unit(e.src), _unit(e.dst)
        if _pkg(a) == _pkg(b) and a != b and a != _pkg(a) and b != _pkg(b):
            graph.setdefault(a, set()).add(b)
            graph.setdefault(b, set())
    lines = []
    for comp in _cycles(graph):
        members = set(comp)
        lines.append(" <-> ".join(comp))
        for e in EDGES:
            if _unit(e.src) in members and _unit(e.dst) in members and _unit(e.src) != _unit(e.dst):
                lines.append(f"    {e.where()}: {e.src} -> {e.dst}{'' if e.top_level else ' (in a function)'}")
    if lines:
        pytest.fail("cycles between parts of a package:\n  " + "\n  ".join(lines), pytrace=False)


def test_the_walk_resolves_relative_and_function_level_imports():
    """The walker on a tiny source: relative imports resolve, a lazy import is an edge but not an import-time
    one, a TYPE_CHECKING import is never import-time; the cycle finder finds a planted cycle."""
    src = (
        "from typing import TYPE_CHECKING\n"
        "from .writer import write_frame\n"
        "from ..render import camera\n"
        "if TYPE_CHECKING:\n"
        "    from rana.model import RANA\n"
        "def f():\n"
        "    from rh_eval.weights import load_backbone\n"
    )
    node = ast.parse(src)
    found = [(n.lineno, top) for n, top in _walk(node, True) if isinstance(n, ast.ImportFrom)]
    assert found == [(1, True), (2, True), (3, True), (5, False), (7, False)]
    rel = ast.parse("from .writer import x").body[0]
    assert _resolve("rh_dataset.cli", rel) == "rh_dataset.writer"  # a module: `.` is its package
    assert _resolve("rh_dataset", rel) == "rh_dataset.writer"  # a package: `.` is itself
    assert _resolve("rh_dataset.generate", rel) == "rh_dataset.generate.writer"
    up = ast.parse("from ..render import camera").body[0]
    assert _resolve("rh_dataset.poses.rig", up) == "rh_dataset.render"
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert _cycles({"a": {"b"}, "b": set()}) == []
    lazy = Edge("rh_dataset.poses.rig", "rh_dataset.characters.body", ("x",), "f.py", 1, True)
    assert _loads(lazy) == ["rh_dataset.characters", "rh_dataset.characters.body"]
