"""The module import graph of ``inbetween_jax`` has no cycles.

Every ``.py`` file of the package is parsed with ``ast`` (nothing is imported) and every ``import`` /
``from ... import`` statement is an edge, **including those inside functions**: a lazy import only postpones a
cycle to the first call and hides which module is the lower layer, so it counts the same as one at the top.
(Imports under ``if TYPE_CHECKING:`` never run and are left out.)  ``from pkg import name`` is an edge to the
module ``pkg.name`` when there is one, else to ``pkg`` (its ``__init__``); names that a package's ``__init__``
loads by ``importlib`` on first use are not edges.  On failure the message lists each cycle with the file and
line of every edge in it.
"""
from __future__ import annotations

import ast
import os

import inbetween_jax

PACKAGE_DIR = os.path.dirname(os.path.abspath(inbetween_jax.__file__))


def package_modules() -> dict:
    """{dotted module name: file path} of every module of the package (``pkg.__init__`` named ``pkg``)."""
    root = os.path.dirname(PACKAGE_DIR)
    out = {}
    for folder, dirs, files in os.walk(PACKAGE_DIR):
        dirs[:] = sorted(d for d in dirs if d != "__pycache__")
        for name in sorted(files):
            if name.endswith(".py"):
                path = os.path.join(folder, name)
                mod = os.path.relpath(path, root)[:-3].replace(os.sep, ".")
                out[mod[: -len(".__init__")] if mod.endswith(".__init__") else mod] = path
    return out


def _type_checking_nodes(tree) -> set:
    skip = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            for child in node.body:
                skip.update(id(n) for n in ast.walk(child))
    return skip


def imports_of(module: str, path: str, modules: dict) -> dict:
    """{imported package module: first line number} of ``module`` (top-level and function-level imports)."""
    with open(path, encoding="utf-8") as f:
        tree = ast.parse(f.read(), path)
    package = module if path.endswith("__init__.py") else module.rpartition(".")[0]
    skip = _type_checking_nodes(tree)
    out = {}
    for node in ast.walk(tree):
        if id(node) in skip:
            continue
        targets = []
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.rsplit(".", node.level - 1)[0] if node.level > 1 else package
                base = f"{base}.{node.module}" if node.module else base
            else:
                base = node.module
            targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in modules else base for a in node.names]
        for t in targets:
            if t in modules and t != module:
                out.setdefault(t, node.lineno)
    return out


def import_graph() -> dict:
    modules = package_modules()
    return {m: imports_of(m, p, modules) for m, p in modules.items()}


def cycles(graph: dict) -> list:
    """The strongly connected components of more than one module (Tarjan), each a sorted list."""
    index, low, stack, on_stack, found = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph[v]:
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
            if len(comp) > 1:
                found.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def test_graph_sees_the_package():
    graph = import_graph()
    assert "inbetween_jax.cli" in graph and "inbetween_jax.data.datasets" in graph
    assert "inbetween_jax.data.sources" in graph["inbetween_jax.data.datasets"]       # a top-level import
    assert "inbetween_jax.train.run" in graph["inbetween_jax.train.select"]
    assert "inbetween_jax.data.datasets" in graph["inbetween_jax.train.select"]       # a function-level one


def test_cycle_finder_finds_a_lazy_cycle():
    assert cycles({"a": {"b": 1}, "b": {"c": 3}, "c": {"a": 9}, "d": {"a": 1}}) == [["a", "b", "c"]]
    assert cycles({"a": {"b": 1}, "b": {}}) == []


def test_no_import_cycles():
    graph = import_graph()
    found = cycles(graph)
    lines = []
    for comp in found:
        lines.append(" <-> ".join(comp))
        lines += [f"    {a} -> {b} (line {graph[a][b]})" for a in comp for b in sorted(graph[a]) if b in comp]
    assert not found, "import cycles:\n" + "\n".join(lines)
