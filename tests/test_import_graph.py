"""The package's floors (issue 22): no import reaches up or sideways.

``docs/architecture.md`` orders the parts of the package in floors (its
"Floors" table, read here, so that the page and the rule cannot drift
apart). Every import statement in the package is checked - at module level
and inside functions alike, since an import hidden in a function is still
an arrow - except those under ``if TYPE_CHECKING:`` (annotations, never
run). A part imports only from itself and from lower floors; nothing
imports in a cycle, between parts or between modules.
"""

from __future__ import annotations

import ast
import re
from collections import defaultdict
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "pysindy_mme"
DOC = ROOT / "docs" / "architecture.md"


def floors() -> dict:
    """``{part: floor}`` from the "Floors" table of docs/architecture.md."""
    text = DOC.read_text(encoding="utf-8")
    section = text.split("## Floors", 1)[1].split("\n## ", 1)[0]
    out = {}
    for floor, parts in re.findall(r"^\|\s*(\d+)\s*\|(.*)\|\s*$", section, re.M):
        # the parts are the backticked names outside parentheses
        for part in re.findall(r"`([\w.]+)`", re.sub(r"\([^)]*\)", "", parts)):
            out[part] = int(floor)
    return out


def _module(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _type_checking_nodes(tree) -> set:
    """Nodes under ``if TYPE_CHECKING:`` (not run)."""
    skip = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            for child in node.body:
                skip.update(id(n) for n in ast.walk(child))
    return skip


def imports() -> dict:
    """``{module: {imported module, ...}}`` over every file of the package."""
    modules = {_module(p): p for p in PACKAGE.rglob("*.py")}
    edges = defaultdict(set)
    for name, path in modules.items():
        package = name if path.name == "__init__.py" else name.rsplit(".", 1)[0]
        tree = ast.parse(path.read_text(encoding="utf-8"))
        skip = _type_checking_nodes(tree)
        for node in ast.walk(tree):
            if id(node) in skip:
                continue
            if isinstance(node, ast.ImportFrom):
                if node.level:
                    base = package.split(".")[
                        : len(package.split(".")) - node.level + 1
                    ]
                    target = ".".join(base + ([node.module] if node.module else []))
                else:
                    target = node.module or ""
                found = [
                    t
                    for t in [target] + [f"{target}.{a.name}" for a in node.names]
                    if t in modules
                ]
            elif isinstance(node, ast.Import):
                found = [a.name for a in node.names if a.name in modules]
            else:
                continue
            edges[name].update(t for t in found if t != name)
    return {m: edges[m] for m in modules}


def part(module: str) -> str:
    """``pysindy_mme.discovery.steps`` -> ``discovery``; the face is
    ``pysindy_mme``."""
    pieces = module.split(".")
    return pieces[1] if len(pieces) > 1 else pieces[0]


GRAPH = imports()
FLOORS = floors()


def test_every_part_of_the_package_has_a_floor():
    missing = sorted({part(m) for m in GRAPH} - set(FLOORS))
    assert not missing, (
        f"parts with no floor in docs/architecture.md: {missing}; add them to "
        "its Floors table"
    )
    gone = sorted(set(FLOORS) - {part(m) for m in GRAPH})
    assert not gone, f"docs/architecture.md names parts that do not exist: {gone}"


def test_no_import_reaches_up_or_sideways():
    bad = []
    for module, targets in GRAPH.items():
        a = part(module)
        for target in targets:
            b = part(target)
            if a != b and FLOORS[b] >= FLOORS[a]:
                way = "up" if FLOORS[b] > FLOORS[a] else "sideways"
                bad.append(
                    f"{module} -> {target} ({way}: {a} floor {FLOORS[a]}, "
                    f"{b} floor {FLOORS[b]})"
                )
    assert not bad, "\n".join(bad)


def test_no_module_imports_in_a_cycle():
    index, low, stack, on, cycles = {}, {}, [], set(), []
    counter = [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in GRAPH[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                cycles.append(sorted(component))

    for v in GRAPH:
        if v not in index:
            visit(v)
    assert not cycles, f"modules importing each other: {cycles}"


@pytest.mark.parametrize(
    "source, expected",
    [
        ("from ..discovery.study import discover", "up"),
        ("from ..optimizers import FloatingFStepwise", "sideways"),
    ],
)
def test_the_check_sees_an_import_hidden_in_a_function(source, expected, tmp_path):
    """The rule's own test: an arrow inside a function body is found."""
    tree = ast.parse(f"def f():\n    {source}\n")
    node = next(n for n in ast.walk(tree) if isinstance(n, ast.ImportFrom))
    target = "pysindy_mme." + node.module.lstrip(".")
    a, b = "solver", part(target)
    way = (
        "up"
        if FLOORS[b] > FLOORS[a]
        else "sideways"
        if FLOORS[b] == FLOORS[a]
        else "down"
    )
    assert way == expected
