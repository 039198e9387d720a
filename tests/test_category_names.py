"""Issue 62: nothing in the library names a category in code outside the built-in spec files.

A category's conventions, ranges, defaults and choices live in its spec (``ancsh/data/specs/*.toml``) or in measured
tables keyed by the name read from it; the library's code never holds a built-in category's name as a string literal.
Outside the scan: the procedural generators (``ancsh/data/procedural/``: the optional extra data source of each
built-in category, one module per category by design), and the benchmarks and commands (``ancsh/studies``,
``ancsh/cli``), which choose what to measure. Docstrings and prose inside longer strings are words, not code.
"""

import ast
from pathlib import Path

from ancsh.data.category_spec import BUILTIN_SPECS_DIR

PACKAGE = Path(__file__).resolve().parents[1] / "ancsh"
#: Folders (relative to the package) outside the scan, and why (the module docstring).
UNSCANNED = ("studies/", "cli/", "data/procedural/", "__main__.py")
#: ``box`` is a word of the library besides a category: an image box of a hint, a part's amodal box in the JSON, a
#: clutter box of a scene. These modules use it so; another use of the literal elsewhere fails the test.
WORD_USES = {
    "box": {"data/isolate/hints.py", "data/scenes.py", "learned/inference/predict.py", "service/client.py",
            "service/http.py", "service/requests.py", "service/service.py"},
}


def category_literals(source: str, names) -> list[tuple[int, str]]:
    """``(line, name)`` of every string literal of ``source`` that is exactly one of ``names`` (docstrings left out)."""
    tree = ast.parse(source)
    docstrings = set()
    for node in ast.walk(tree):
        body = getattr(node, "body", None)
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) and body \
                and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant):
            docstrings.add(id(body[0].value))
    return sorted((node.lineno, node.value) for node in ast.walk(tree)
                  if isinstance(node, ast.Constant) and isinstance(node.value, str) and node.value in names
                  and id(node) not in docstrings)


def test_the_scanner_finds_a_category_named_in_code_and_not_in_words():
    source = ('"""The laptop module: laptop."""\n'
              'def f(c):\n    """laptop"""\n    return CONVENTIONS["laptop"] if c == "oven" else "a laptop"\n')
    assert category_literals(source, {"laptop", "oven"}) == [(4, "laptop"), (4, "oven")]


def test_no_library_module_names_a_built_in_category():
    names = {path.stem for path in BUILTIN_SPECS_DIR.glob("*.toml")}
    assert {"laptop", "drawer", "box"} <= names  # the built-in specs are where the names come from
    found = []
    for path in sorted(PACKAGE.rglob("*.py")):
        rel = path.relative_to(PACKAGE).as_posix()
        if rel.startswith(UNSCANNED):
            continue
        for line, name in category_literals(path.read_text(), names):
            if rel not in WORD_USES.get(name, ()):
                found.append(f"ancsh/{rel}:{line}: {name!r}")
    assert found == [], "category names in library code (move the choice into the spec):\n" + "\n".join(found)
