"""Category spec files: the built-in categories read from them, wrong specs named by file and key,
categories from a spec known to the importer and the renderer."""

from __future__ import annotations

import dataclasses
import os
import tomllib

import numpy as np
import pytest

from ancsh.data import category_spec
from ancsh.data.category_spec import SpecError, load_spec, parse_spec, spec_text
from ancsh.data.conventions import CONVENTIONS, convention, convention_violations, register_category, resolve_category
from ancsh.data.importer import ImportRejected, import_object


def test_every_builtin_category_is_its_spec_file_and_writes_back_to_it():
    assert list(CONVENTIONS.builtin) == [p.stem for p in category_spec.builtin_spec_paths()]
    for path in category_spec.builtin_spec_paths():
        conv = load_spec(path)
        assert conv.spec_path == str(path) and conv.folder is None
        assert dataclasses.replace(conv, spec_path=None) == CONVENTIONS[conv.name]
        back = parse_spec(tomllib.loads(spec_text(conv)), "round trip")
        assert back == dataclasses.replace(conv, spec_path=None)


def test_the_units_of_a_spec_are_read_into_radians_and_metres(tmp_path, make_category_spec):
    conv = load_spec(make_category_spec(tmp_path))
    assert conv.joints[0].state_range == (0.0, np.pi) and conv.joints[0].side == ("front",)
    assert conv.joint_limits.tolist() == [[0.0, np.pi]]
    assert convention("drawer").joints[0].type.value == "prismatic"
    assert load_spec(category_spec.BUILTIN_SPECS_DIR / "laptop.toml").rest_states[0] == np.pi / 2


@pytest.mark.parametrize("edit, key, words", [
    (("name = \"toaster\"", "name = \"toaster\"\ncolour = \"red\""), "colour", "unknown key"),
    (("range_deg = [0, 180]", "range_dge = [0, 180]"), "joints[0].range_dge", "unknown key"),
    (("spec_version = 1", "spec_version = 2"), "spec_version", "expected 1"),
    (("range_deg = [0, 180]", "range_m = [0, 1]"), "joints[0].range_m", "range_deg or range_rad"),
    (("range_deg = [0, 180]", ""), "joints[0].range_deg", "exactly one of"),
    (("rest_deg = 0", "rest_deg = 0\nrest_rad = 0"), "joints[0].rest_deg", "exactly one of"),
    (("range_deg = [0, 180]", "range_deg = [180, 0]"), "joints[0].range_deg", "lower < upper"),
    (("rest_deg = 0", "rest_deg = 200"), "joints[0].range", "outside"),
    (('type = "revolute"', 'type = "ball"'), "joints[0].type", "'revolute' or 'prismatic'"),
    (('child = "door"', 'child = "lid"'), "joints[0].child", "moves part 1"),
    (('zero = "closed"', 'zero = "shut"'), "joints[0].zero", "expected one of"),
    (('side = "front"', 'side = "left"'), "joints[0].side", "expected one or more"),
    (("diagonal_m = [0.5, 1.5]", "diagonal_m = [0.5]"), "diagonal_m", "[lower, upper]"),
    (("diagonal_m = [0.5, 1.5]", "diagonal_m = [0.5, 1.5]\n[viewpoint]\nazimuth = [0, 1]"), "viewpoint.azimuth",
     "unknown key"),
    (("diagonal_m = [0.5, 1.5]", "diagonal_m = [0.5, 1.5]\n[viewpoint]\nelevation_deg = [0, 95]"), "viewpoint",
     "elevation"),
    (('name = "base"', 'name = "base"\nsemantics = ["body"]'), "parts[0].semantics", "the base"),
    (('name = "toaster"', 'name = "Toaster!"'), "name", "lower-case"),
])
def test_a_wrong_spec_names_its_file_and_key(tmp_path, edit, key, words, make_category_spec):
    path = make_category_spec(tmp_path)
    text = path.read_text()
    assert edit[0] in text
    path.write_text(text.replace(edit[0], edit[1], 1))
    with pytest.raises(SpecError) as exc:
        load_spec(path)
    message = str(exc.value)
    assert message.startswith(f"{path}: {key}") and words in message, message


def test_a_spec_viewpoint_is_how_its_frames_are_rendered(tmp_path, clean_registry, make_category_spec):
    from ancsh.data.conventions import CONVENTIONS
    from ancsh.data.render import DEFAULT_VIEWPOINT, ViewpointRange, viewpoint_range

    path = make_category_spec(tmp_path)
    path.write_text(path.read_text().replace("diagonal_m = [0.5, 1.5]", "diagonal_m = [0.5, 1.5]\n[viewpoint]\n"
                                             "azimuth_deg = [-30, 30]\nroll_deg = 0"))
    name = resolve_category(str(path))
    assert viewpoint_range(name) == ViewpointRange(azimuth=(-np.pi / 6, np.pi / 6), roll=0.0)
    plain = resolve_category(str(make_category_spec(tmp_path, name="plain")))
    assert viewpoint_range(plain) == DEFAULT_VIEWPOINT
    assert viewpoint_range("box").distance == (1.8, 4.0)  # the built-in spec's
    # a convention itself (a loaded category's) gives its spec's range as its name does
    assert viewpoint_range(CONVENTIONS[name]) == viewpoint_range(name)
    assert viewpoint_range(CONVENTIONS[plain]) == DEFAULT_VIEWPOINT


def test_a_file_that_is_no_toml_or_no_spec_says_so(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("name = [unclosed")
    with pytest.raises(SpecError, match="not valid TOML"):
        load_spec(bad)
    with pytest.raises(SpecError, match="holds no category.toml"):
        load_spec(tmp_path)
    with pytest.raises(SpecError, match="no such category spec"):
        load_spec(tmp_path / "missing.toml")


def test_a_category_folder_registers_once_and_is_found_by_name(tmp_path, clean_registry, make_category_spec):
    folder = tmp_path / "toaster"
    make_category_spec(folder, file="category.toml")
    assert "toaster" not in CONVENTIONS
    assert resolve_category(str(folder)) == "toaster"
    conv = convention("toaster")
    assert conv.folder == str(folder) and "toaster" in list(CONVENTIONS)
    assert str(folder.resolve()) in os.environ[category_spec.SEARCH_PATH_VARIABLE]  # worker processes know it
    assert resolve_category("toaster") == "toaster"
    from ancsh.learned.inference.confidence import calibration_path
    from ancsh.learned.network.weights import WEIGHTS_DIR, weights_path

    assert weights_path("toaster") == folder / "toaster.pt" and calibration_path("toaster").parent == folder
    assert weights_path("laptop") == WEIGHTS_DIR / "laptop.pt"
    same = make_category_spec(tmp_path / "elsewhere")  # the same definition in another file: the same category, the later one used
    assert register_category(same).spec_path == str(same.resolve())
    other = make_category_spec(tmp_path / "other", extra='description = "another toaster"')  # another definition of the name
    with pytest.raises(SpecError, match="already the category of"):
        register_category(other)
    with pytest.raises(SpecError, match="already a built-in category"):
        register_category(make_category_spec(tmp_path, name="laptop"))


def test_the_search_path_finds_spec_files_and_folders(tmp_path, clean_registry, monkeypatch, make_category_spec):
    root = tmp_path / "cats"
    make_category_spec(root, name="toaster")
    make_category_spec(root / "kettle", name="kettle", file="category.toml")
    monkeypatch.setenv(category_spec.SEARCH_PATH_VARIABLE, str(root))
    assert {"toaster", "kettle"} <= set(CONVENTIONS)
    assert convention("kettle").folder == str(root / "kettle") and convention("toaster").folder is None
    monkeypatch.setenv(category_spec.SEARCH_PATH_VARIABLE, "")
    assert "toaster" not in CONVENTIONS


def test_a_spec_category_imports_an_object_by_its_own_rules(tmp_path, make_oven_urdf, clean_registry, make_category_spec):
    """A category the library does not know, from a spec: the importer maps the synthetic oven onto it."""
    name = resolve_category(str(make_category_spec(tmp_path)))
    obj = import_object(make_oven_urdf(tmp_path / "t1"), name)
    assert obj.category == "toaster" and obj.moving_links == ("door",)
    assert convention_violations(obj.model(), convention(name)) == []
    reference = import_object(make_oven_urdf(tmp_path / "t2"), "oven")
    assert obj.zero == pytest.approx(reference.zero) and obj.sign == reference.sign


def test_link_patterns_and_freeze_choose_the_moving_part_without_semantics(tmp_path, make_oven_urdf, clean_registry, make_category_spec):
    """Without semantics.txt every movable link is a candidate: the knob, the door and a hatch. ``links`` patterns
    keep the door; ``freeze`` drops the knob and the hatch; with neither, the importer must choose."""
    urdf = make_oven_urdf(tmp_path / "o", hatch=True)
    (urdf.parent / "semantics.txt").unlink()
    by_links = resolve_category(str(make_category_spec(tmp_path, name="by_links", part='links = ["do*"]')))
    assert import_object(urdf, by_links).moving_links == ("door",)
    frozen = resolve_category(str(make_category_spec(tmp_path, name="frozen", part="", extra='freeze = ["knob", "hatch"]')))
    obj = import_object(urdf, frozen)
    assert obj.moving_links == ("door",) and obj.joint_types["knob_joint"] == "fixed"
    wrong = resolve_category(str(make_category_spec(tmp_path, name="wrong", part='links = ["lid*"]')))
    with pytest.raises(ImportRejected, match="has 0 moving part"):
        import_object(urdf, wrong)


def test_a_spec_category_without_a_generator_renders_its_catalog_only(tmp_path, make_oven_urdf, clean_registry, make_category_spec):
    from ancsh.data.catalog import build_catalog, write_catalog
    from ancsh.data.generate import FrameGenerator, GenerationConfig
    from ancsh.data.render import Intrinsics

    name = resolve_category(str(make_category_spec(tmp_path)))
    with pytest.raises(ValueError, match="no procedural generator"):
        GenerationConfig(category=name)
    urdfs = [make_oven_urdf(tmp_path / f"toaster_{i}") for i in range(3)]
    catalog = build_catalog(urdfs, name)
    path = write_catalog(catalog, tmp_path / "catalog.json")
    split = catalog.objects[0].split
    config = GenerationConfig(category=name, split=split, real=str(path), intrinsics=Intrinsics.kinect(160, 120),
                              num_points=64)
    assert config.real_fraction == 1.0
    with pytest.raises(ValueError, match="real_fraction 1"):
        GenerationConfig(category=name, real=str(path), real_fraction=0.5)
    assert "generator_version" not in config.to_json()
    gen = FrameGenerator(config)
    assert gen.num_instances == len(catalog.instances(name, split)) and gen.num_instances > 0
    other = "train" if split == "test" else "test"
    if not catalog.instances(name, other):
        with pytest.raises(ValueError, match="holds no toaster object"):
            FrameGenerator(dataclasses.replace(config, split=other))


def test_a_report_records_the_category_as_given_on_the_command_line(tmp_path, make_category_spec, clean_registry):
    """``--category path/to/spec.toml`` runs under the spec's name, and the command a report records (``ancsh
    evaluate``'s, ``ancsh calibrate``'s) names the file again, so that it runs elsewhere; a name stays a name."""
    from ancsh.cli import build_parser
    from ancsh.cli.learned import _calibrate_output, _rebuild

    spec = make_category_spec(tmp_path)
    args = build_parser().parse_args(["evaluate", "--category", str(spec), "--frames", "10", "--out", str(tmp_path)])
    assert args.category == "toaster" and str(spec) in _rebuild(args)
    assert type(args.category) is str  # a plain name: it goes into configs, checkpoints and worker processes
    args = build_parser().parse_args(["calibrate", "--category", str(spec), "--frames", "10", "--out", str(tmp_path)])
    assert f"--category {spec}" in _calibrate_output(args)[1]
    args = build_parser().parse_args(["evaluate", "--category", "laptop", "--frames", "10"])
    assert "--category laptop " in _rebuild(args)
