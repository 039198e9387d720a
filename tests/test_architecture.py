"""The layout of docs/ARCHITECTURE.md, enforced: imports run from a higher floor to a lower one (or within one
floor), no module imports itself through others (no circles), and modules over 700 lines say why."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "ancsh"

# Modules over this many lines say why, on a line of their docstring's first paragraph that starts with "Long:".
MAX_LINES = 700

# Floors from the bottom up (docs/ARCHITECTURE.md's picture). A module belongs to the floor of the longest prefix
# of its name listed here; it may import its own floor and the floors below it, never one above.
FLOORS = [
    ("infrastructure", ("ancsh._version", "ancsh._machine", "ancsh.outputs", "ancsh.executors")),
    ("geometry", ("ancsh.geometry",)),
    ("model", ("ancsh.model",)),
    ("data", ("ancsh.data",)),
    ("solvers", ("ancsh.solvers",)),
    ("evaluation", ("ancsh.evaluation",)),
    ("learned (devices, distributed)", ("ancsh.learned",)),
    ("learned.network", ("ancsh.learned.network",)),
    ("learned.inference", ("ancsh.learned.inference",)),
    ("learned.training", ("ancsh.learned.training",)),
    ("tracking", ("ancsh.tracking",)),
    ("service", ("ancsh.service",)),
    ("studies", ("ancsh.studies",)),
    ("commands", ("ancsh.cli", "ancsh.__main__", "ancsh")),
]

def module_name(path: Path) -> str:
    parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def floor_of(module: str) -> int:
    best, floor = -1, None
    for index, (_, prefixes) in enumerate(FLOORS):
        for prefix in prefixes:
            if (module == prefix or module.startswith(prefix + ".")) and len(prefix) > best:
                best, floor = len(prefix), index
    if floor is None:
        raise KeyError(f"module {module} is on no floor of FLOORS")
    return floor


def imports_of(path: Path, modules: set[str]) -> set[str]:
    """The ancsh modules one file imports, at its top or inside functions (relative imports resolved)."""
    name = module_name(path)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        targets = []
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                module = ".".join(base + ([node.module] if node.module else []))
            else:
                module = node.module or ""
            targets = [f"{module}.{alias.name}" if f"{module}.{alias.name}" in modules else module
                       for alias in node.names]
        elif isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        found.update(t for t in targets if t == "ancsh" or t.startswith("ancsh."))
    return found


def import_graph() -> dict[str, set[str]]:
    paths = sorted(PACKAGE.rglob("*.py"))
    modules = {module_name(p) for p in paths}
    return {module_name(p): imports_of(p, modules) for p in paths}


def upward_imports(graph: dict[str, set[str]]) -> list[str]:
    """Every import from a floor to a higher one, as readable lines."""
    return [f"{src} (floor {FLOORS[floor_of(src)][0]}) imports {dst} (floor {FLOORS[floor_of(dst)][0]})"
            for src, targets in sorted(graph.items()) for dst in sorted(targets)
            if floor_of(dst) > floor_of(src)]


def circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan, iterative)."""
    index, low, on_stack, stack, found, counter = {}, {}, set(), [], [], [0]
    for root in graph:
        if root in index:
            continue
        work = [(root, iter(sorted(graph.get(root, ()))))]
        index[root] = low[root] = counter[0]
        counter[0] += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = counter[0]
                    counter[0] += 1
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


def test_the_checks_catch_an_upward_import_and_a_circle():
    graph = {"ancsh.geometry.a": {"ancsh.solvers.b"}, "ancsh.solvers.b": {"ancsh.solvers.c"},
             "ancsh.solvers.c": {"ancsh.solvers.b"}}
    assert upward_imports(graph) == ["ancsh.geometry.a (floor geometry) imports ancsh.solvers.b (floor solvers)"]
    assert circles(graph) == [["ancsh.solvers.b", "ancsh.solvers.c"]]
    with pytest.raises(KeyError, match="no floor"):
        floor_of("numpy.linalg")


def test_every_module_is_on_a_floor_and_no_import_runs_upward():
    graph = import_graph()
    for module in graph:
        floor_of(module)
    assert upward_imports(graph) == []


def test_no_module_imports_itself_through_others():
    assert circles(import_graph()) == []


def unexplained_long_modules(paths) -> list[str]:
    """Modules over :data:`MAX_LINES` lines without a "Long:" line in their docstring's first paragraph."""
    found = []
    for path in paths:
        text = Path(path).read_text()
        if text.count("\n") > MAX_LINES:
            doc = ast.get_docstring(ast.parse(text)) or ""
            if not any(line.startswith("Long:") for line in doc.split("\n\n")[0].splitlines()):
                found.append(f"{Path(path).name} ({text.count(chr(10))} lines)")
    return found


def test_the_long_module_check_asks_for_a_reason(tmp_path):
    body = "x = 1\n" * (MAX_LINES + 1)
    bare, explained = tmp_path / "bare.py", tmp_path / "explained.py"
    bare.write_text('"""A module."""\n' + body)
    explained.write_text('"""A module.\nLong: one table of data."""\n' + body)
    assert unexplained_long_modules([bare, explained]) == [f"bare.py ({MAX_LINES + 2} lines)"]


def test_long_modules_say_why():
    assert unexplained_long_modules(sorted(PACKAGE.rglob("*.py"))) == []
