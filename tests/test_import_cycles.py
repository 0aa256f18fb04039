"""No import cycle among the modules of the seapup packages.

A cycle (``a`` imports ``b`` imports ... imports ``a``) makes the import order
matter and ties the modules on it into one unit: none of them can be read,
tested or moved alone. The walk here is self-contained (the AST of every
module under ``ros2_ws/src/<package>/<package>/``, tests excluded) and counts
every import statement, also those inside functions: a lazy import still ties
the two modules together. It resolves

- absolute imports (``import a.b``, ``from a.b import c``),
- relative imports (``from . import c``, ``from ..b import c``),
- ``from a import b`` where ``b`` is a submodule (an edge to ``a.b``),

to the deepest module that exists, and reports every strongly connected
component of more than one module (Tarjan's algorithm).
"""
from __future__ import annotations

import ast
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "ros2_ws" / "src"


def modules(src: Path) -> dict[str, Path]:
    """Every module of the Python packages ``src/<package>/<package>/``: dotted name -> path."""
    out = {}
    for package_dir in sorted(p for p in src.iterdir() if (p / p.name / "__init__.py").is_file()):
        for path in sorted((package_dir / package_dir.name).rglob("*.py")):
            name = ".".join(path.relative_to(package_dir).with_suffix("").parts)
            out[name.removesuffix(".__init__")] = path
    return out


def _package_of(module: str, path: Path) -> str:
    """The package a module's relative imports start from."""
    return module if path.name == "__init__.py" else module.rpartition(".")[0]


def _imported_names(node: ast.AST, package: str) -> list[str]:
    """Dotted names one import statement may load (a ``from`` import: the module and each name in it)."""
    if isinstance(node, ast.Import):
        return [alias.name for alias in node.names]
    if not isinstance(node, ast.ImportFrom):
        return []
    base = node.module or ""
    if node.level:
        parts = package.split(".")
        parts = parts[:len(parts) - node.level + 1]
        base = ".".join(parts + ([base] if base else []))
    return [base] + [f"{base}.{alias.name}" for alias in node.names if alias.name != "*"]


def _resolve(name: str, known: dict[str, Path]) -> str | None:
    """The deepest known module a dotted name lies in, or None (not a project module)."""
    while name and name not in known:
        name = name.rpartition(".")[0]
    return name or None


def import_graph(known: dict[str, Path]) -> dict[str, set[str]]:
    """Module -> the project modules it imports (a package's own ancestors left out)."""
    edges = {}
    for module, path in known.items():
        package = _package_of(module, path)
        targets = set()
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            for name in _imported_names(node, package):
                target = _resolve(name, known)
                if target and target != module and not module.startswith(target + "."):
                    targets.add(target)
        edges[module] = targets
    return edges


def cycles(edges: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan, iterative), each sorted."""
    index, low, on_stack, stack, found = {}, {}, set(), [], []
    for root in sorted(edges):
        if root in index:
            continue
        work = [(root, iter(sorted(edges[root])))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        while work:
            vertex, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = len(index)
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(edges.get(child, ())))))
                elif child in on_stack:
                    low[vertex] = min(low[vertex], index[child])
                continue
            work.pop()
            if work:
                parent = work[-1][0]
                low[parent] = min(low[parent], low[vertex])
            if low[vertex] == index[vertex]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == vertex:
                        break
                if len(component) > 1:
                    found.append(sorted(component))
    return found


def test_the_walk_sees_every_package():
    known = modules(SRC)
    assert {m.split(".")[0] for m in known} >= {"seapup_common", "seapup_sim", "seapup_control", "seapup_ident",
                                                  "seapup_bringup"}
    assert "seapup_bringup.cli" in known and len(known) >= 60


def test_no_import_cycle():
    found = cycles(import_graph(modules(SRC)))
    assert not found, "import cycles: " + "; ".join(" <-> ".join(c) for c in found)


def _package(root: Path, name: str, files: dict[str, str]) -> None:
    directory = root / name / name
    directory.mkdir(parents=True)
    (directory / "__init__.py").write_text("")
    for module, text in files.items():
        (directory / f"{module}.py").write_text(text)


def test_the_checker_finds_a_cycle_through_a_lazy_import(tmp_path):
    """Two modules importing each other (one of them inside a function) are one cycle."""
    _package(tmp_path, "pkg", {"registry": "def main():\n    from pkg.helpers import emit\n",
                               "helpers": "from pkg.registry import main\n"})
    assert cycles(import_graph(modules(tmp_path))) == [["pkg.helpers", "pkg.registry"]]


def test_the_checker_resolves_relative_and_submodule_imports(tmp_path):
    """``from . import b`` (b a submodule) and ``from .a import x`` close a cycle; a chain does not."""
    _package(tmp_path, "pkg", {"a": "from . import b\n", "b": "from .a import x\n", "c": "import pkg.a\n"})
    known = modules(tmp_path)
    edges = import_graph(known)
    assert edges["pkg.a"] == {"pkg.b"} and edges["pkg.b"] == {"pkg.a"} and edges["pkg.c"] == {"pkg.a"}
    assert cycles(edges) == [["pkg.a", "pkg.b"]]
    (known["pkg.b"]).write_text("import json\n")
    assert cycles(import_graph(known)) == []
