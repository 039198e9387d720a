"""docs/results/README.md indexes every committed report: each top-level report and file, and each folder, is named
in it (a category's reports as ``<category>...``), so the index cannot fall behind the folder."""

from __future__ import annotations

from pathlib import Path

import pytest

from ancsh.data.procedural import CATEGORY_INFO

RESULTS = Path(__file__).resolve().parents[1] / "docs" / "results"


def index_name(path: Path) -> str:
    """How the index names a top-level entry: ``folder/``, or the file name with a leading category as
    ``<category>``."""
    if path.is_dir():
        return f"{path.name}/"
    for category in sorted(CATEGORY_INFO, key=len, reverse=True):  # washing_machine before any shorter prefix
        if path.name.startswith(f"{category}_") or path.name.startswith(f"{category}."):
            return "<category>" + path.name[len(category):]
    return path.name


def unindexed(entries, index_text: str) -> list[str]:
    """The entries (top-level paths of the results folder) named in ``index_text`` neither as they are nor in their
    category form (:func:`index_name`); a ``.json`` or ``.png`` counts as named where a report of its stem (or its
    stem's first words) is."""
    missing = []
    for path in entries:
        names = {index_name(path), path.name if not path.is_dir() else f"{path.name}/"}
        if any(_named(name, path.suffix, index_text) for name in names):
            continue
        missing.append(index_name(path))
    return sorted(set(missing))


def _named(name: str, suffix: str, index_text: str) -> bool:
    if f"`{name}" in index_text:
        return True
    if suffix in (".json", ".png"):
        stem = name[: -len(suffix)]
        stems = [stem] + [stem.rsplit("_", k)[0] for k in range(1, stem.count("_") + 1)]
        return any(f"`{s}.md`" in index_text for s in stems)
    return False


def test_the_index_check_finds_an_unnamed_report_and_a_folder(tmp_path):
    (tmp_path / "new_report.md").write_text("# x\n")
    (tmp_path / "new_report.json").write_text("{}")
    (tmp_path / "laptop_new.md").write_text("# x\n")
    (tmp_path / "scratch").mkdir()
    entries = sorted(tmp_path.iterdir())
    assert unindexed(entries, "") == ["<category>_new.md", "new_report.json", "new_report.md", "scratch/"]
    assert unindexed(entries, "`new_report.md` `<category>_new.md` `scratch/`") == []


@pytest.mark.skipif(not (RESULTS / "README.md").is_file(), reason="no docs/results/README.md in this checkout")
def test_every_committed_report_is_in_the_results_index():
    text = (RESULTS / "README.md").read_text()
    entries = [p for p in sorted(RESULTS.iterdir()) if p.name != "README.md"]
    assert unindexed(entries, text) == []
