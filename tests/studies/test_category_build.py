"""``ancsh category check`` / ``build``: a category the library has never seen, from a spec and URDFs, through
import, rendering, training, template, evaluation and ``predict``; wrong specs stop before any training."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from ancsh.cli import main

@pytest.fixture
def toasters(tmp_path, make_oven_urdf):
    """Three synthetic ovens' URDF files, named so that two are train objects and one a test object (the split by
    name)."""
    return [str(make_oven_urdf(tmp_path / "urdfs" / f"toaster_{i}")) for i in (2, 3, 4)]


def _write(folder, make_category_spec, edit=lambda text: text, name="toaster.toml"):
    """The oven-like spec file (``make_category_spec``), its text changed by ``edit``."""
    path = make_category_spec(folder, file=name)
    path.write_text(edit(path.read_text()))
    return path


def test_check_lists_what_imports_and_a_wrong_spec_names_file_and_key(tmp_path, toasters, capsys, clean_registry,
                                                                     make_category_spec):
    spec = _write(tmp_path, make_category_spec)
    assert main(["category", "check", str(spec), "--urdfs", *toasters, "--out", str(tmp_path / "cat")]) == 0
    out = capsys.readouterr().out
    assert "| toaster_4 | test | imported |" in out and "3 imported (2 train, 1 test), 0 rejected" in out
    assert json.loads((tmp_path / "cat" / "catalog.json").read_text())["objects"]
    bad = _write(tmp_path, make_category_spec, lambda text: text.replace("range_deg", "range_dg"), "bad.toml")
    assert main(["category", "check", str(bad)]) == 2
    assert f"{bad}: joints[0].range_dg: unknown key" in capsys.readouterr().err


@pytest.mark.parametrize("edit, words", [
    (('type = "revolute"', 'type = "prismatic"'), "joints[0].type 'prismatic'"),  # a joint type the files lack
    (('semantics = ["door"]', 'semantics = ["lid"]'), "parts[1].semantics (lid)"),  # no URDF matches the part
])
def test_urdfs_that_cannot_make_the_category_stop_before_anything_is_rendered(tmp_path, toasters, capsys, edit, words,
                                                                               clean_registry, make_category_spec):
    def change(text):
        text = text.replace(edit[0], edit[1])
        if "prismatic" in edit[1]:
            text = text.replace("rest_deg = 0", "rest_m = 0").replace("range_deg = [0, 180]", "range_m = [0, 0.5]")
        return text

    spec = _write(tmp_path, make_category_spec, change)
    out = tmp_path / "cat"
    assert main(["category", "build", str(spec), "--urdfs", *toasters, "--out", str(out), "--size", "notebook"]) == 2
    err = capsys.readouterr().err
    assert str(spec) in err and "no URDF has the moving parts the spec names" in err and words in err, err
    assert not (out / "data").exists() and not (out / "run").exists()


def test_a_folder_without_its_network_says_how_to_finish_it(tmp_path, toasters, capsys, clean_registry,
                                                            make_category_spec):
    out = tmp_path / "cat"
    assert main(["category", "check", str(_write(tmp_path, make_category_spec)), "--urdfs", *toasters,
                 "--out", str(out)]) == 0
    np.save(tmp_path / "depth.npy", np.full((4, 4), 1.0))
    (tmp_path / "K.json").write_text(json.dumps({"fx": 4, "fy": 4, "cx": 2, "cy": 2, "width": 4, "height": 4}))
    capsys.readouterr()
    assert main(["predict", "--depth", str(tmp_path / "depth.npy"), "--intrinsics", str(tmp_path / "K.json"),
                 "--category", str(out)]) == 2
    err = capsys.readouterr().err
    assert "has no network yet" in err and "ancsh category build" in err and str(out) in err, err


def test_a_notebook_size_build_is_a_category_predict_uses_and_resumes(tmp_path, toasters, capsys, clean_registry,
                                                                      make_category_spec):
    """The build writes the network, the template and the report into the folder; ``--category FOLDER`` predicts
    with them; the same command again keeps every finished step."""
    spec = _write(tmp_path, make_category_spec)
    out = tmp_path / "toaster_category"
    words = ["category", "build", str(spec), "--urdfs", *toasters, "--out", str(out), "--size", "notebook",
             "--train-frames", "24", "--test-frames", "8", "--max-steps", "3", "--evaluate-frames", "2",
             "--workers", "1"]
    assert main(words) == 0
    for name in ("category.toml", "catalog.json", "import_report.md", "toaster.pt", "template.json", "report.md",
                 "evaluation/toaster.md"):
        assert (out / name).is_file(), name
    report = (out / "report.md").read_text()
    assert "2 train, 1 test" in report and "Table 1" in report and "Only 3 objects" in report
    pictures = re.findall(r"\]\(([^)]+\.png)\)", report)
    assert pictures and all((out / p).is_file() for p in pictures), pictures  # linked from the folder's top
    assert f"ancsh evaluate --category {out} " in report  # the evaluation's command runs again as written
    capsys.readouterr()
    assert main(words) == 0
    again = capsys.readouterr().out
    assert "evaluate: kept" in again and "template: kept" in again and "(0 new" in again

    from ancsh.data.catalog import load_catalog
    from ancsh.data.render import Intrinsics, render_depth, sample_viewpoint

    obj = load_catalog(out / "catalog.json").instances("toaster", "test")[0]
    model = obj.model()
    q = model.rest_states + 0.5
    K = Intrinsics.kinect(160, 120)
    depth = render_depth(model, q, sample_viewpoint("toaster", np.random.default_rng(0), model, q), K).depth
    np.save(tmp_path / "depth.npy", depth)
    (tmp_path / "K.json").write_text(json.dumps({"fx": K.fx, "fy": K.fy, "cx": K.cx, "cy": K.cy, "width": K.width,
                                                 "height": K.height}))
    code = main(["predict", "--depth", str(tmp_path / "depth.npy"), "--intrinsics", str(tmp_path / "K.json"),
                 "--category", str(out), "--out", str(tmp_path / "result.json")])
    result = json.loads((tmp_path / "result.json").read_text())
    assert code in (0, 1) and result["category"] == "toaster", result.get("category")
    from ancsh.learned.inference.predict import predict_depth

    pred = predict_depth(depth, K, str(out), mask=depth > 0)  # the Python API takes the folder too
    assert pred.category == "toaster"
