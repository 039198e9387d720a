"""The studies' one writer: provenance measured at run time, atomic writes that replace a symbolic link instead of
writing through it, and figures named as matplotlib names them."""

import json
import os

import pytest

from ancsh._machine import machine_facts
from ancsh.studies.report import Provenance, save_figure, utc_date, write_json, write_text


def test_provenance_records_the_command_date_and_machine_of_the_run():
    p = Provenance("ancsh bench fit --quick")
    assert p.command == "ancsh bench fit --quick" and p.date.endswith(" UTC") and len(p.date) == len(utc_date())
    assert p.machine["cpu_count"] == machine_facts()["cpu_count"] == os.cpu_count()
    assert p.machine_text.startswith(f"{os.cpu_count()} CPU cores")


def test_writes_create_the_folder_and_leave_no_temporary_file(tmp_path):
    path = write_text(tmp_path / "a" / "b" / "report.md", "# title\n")
    assert path.read_text() == "# title\n" and sorted(p.name for p in path.parent.iterdir()) == ["report.md"]
    assert write_json(tmp_path / "r.json", {"x": 1}).read_text() == '{"x": 1}'
    assert write_json(tmp_path / "s.json", {"x": 1}, indent=1).read_text() == '{\n "x": 1\n}\n'


def test_a_symlinked_output_is_replaced_not_written_through(tmp_path):
    elsewhere = tmp_path / "other_folder" / "precious.md"
    elsewhere.parent.mkdir()
    elsewhere.write_text("keep me")
    link = tmp_path / "out" / "report.md"
    link.parent.mkdir()
    link.symlink_to(elsewhere)
    write_text(link, "report")
    assert elsewhere.read_text() == "keep me" and not link.is_symlink() and link.read_text() == "report"


def test_an_interrupted_write_keeps_the_old_file(tmp_path, monkeypatch):
    path = write_text(tmp_path / "report.md", "old")

    def fail(*args, **kwargs):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "replace", fail)
    with pytest.raises(OSError, match="No space"):
        write_text(path, "new")
    assert path.read_text() == "old" and sorted(p.name for p in tmp_path.iterdir()) == ["report.md"]


def test_figures_are_written_atomically_with_matplotlibs_naming(tmp_path):
    from matplotlib.figure import Figure

    fig = Figure(figsize=(1, 1))
    fig.add_subplot().plot([0, 1], [0, 1])
    assert save_figure(fig, tmp_path / "plot") == tmp_path / "plot.png"  # no suffix: .png, as matplotlib does
    assert (tmp_path / "plot.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert save_figure(fig, tmp_path / "plot.svg", dpi=50).read_text().lstrip().startswith("<?xml")
    with pytest.raises(ValueError, match="not supported"):
        save_figure(fig, tmp_path / "plot.xyz")
    assert json.dumps(sorted(p.name for p in tmp_path.iterdir())) == '["plot.png", "plot.svg"]'
