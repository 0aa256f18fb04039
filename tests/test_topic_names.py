"""One topic table: code names the graph's topics through :mod:`seapup_common.topics`, not literals.

An AST walk of every module of the listed packages (docstrings and prose left
alone: a string with a space is a sentence) flags a string constant that is a
graph name (``"/seapup/..."``, ``"/seapup"``, ``"/clock"``, ``"/diagnostics"``),
starts an f-string with one, or quotes one inside a parameter value
(``"wait_for_subscribers:=['/seapup/...']"``). Node shells keep their
remappable names relative to their namespace (``"sensors/velocity"``).
"""
import ast
import re
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "ros2_ws" / "src"
#: seapup_control joins once its node shells take their absolute names from the table.
PACKAGES = ("seapup_common", "seapup_sim", "seapup_ident", "seapup_control", "seapup_runs", "seapup_live_view",
            "seapup_bringup")
TABLE = SRC / "seapup_common" / "seapup_common" / "topics.py"
GRAPH_NAME = re.compile(r"""(^|['"\[])/(seapup|clock|diagnostics)(/|$|['"\]])""")


def _docstring_ids(tree: ast.AST) -> set[int]:
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) and node.body:
            first = node.body[0]
            if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant):
                out.add(id(first.value))
    return out


def literal_names(source: str) -> list[tuple[int, str]]:
    """(line, text) of each string constant in ``source`` that spells a graph name."""
    tree = ast.parse(source)
    docstrings = _docstring_ids(tree)
    return [(node.lineno, node.value) for node in ast.walk(tree)
            if isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in docstrings
            and " " not in node.value and GRAPH_NAME.search(node.value)]


def _modules():
    for package in PACKAGES:
        yield from (p for p in sorted((SRC / package / package).rglob("*.py")) if p != TABLE)


@pytest.mark.parametrize("path", list(_modules()), ids=lambda p: str(p.relative_to(SRC)))
def test_no_literal_graph_names(path):
    found = literal_names(path.read_text())
    assert not found, f"{path.name}: use seapup_common.topics instead of {found}"


def test_the_scan_finds_literals_and_leaves_prose_and_relative_names():
    source = '''"""Reads /seapup/sensors/velocity."""
def f(node, kind):
    """Publishes on "/clock"."""
    node.create_subscription(T, "/seapup/sensors/velocity", print, 10)
    node.create_publisher(T, "sensors/velocity", 10)
    node.create_publisher(T, "/clock", 10)
    print("publishes /clock (the simulator owns time)")
    return [f"/seapup/task/{kind}", "wait_for_subscribers:=['/seapup/truth/odometry']", "/seapupx"]
'''
    assert [line for line, _ in literal_names(source)] == [4, 6, 8, 8]
