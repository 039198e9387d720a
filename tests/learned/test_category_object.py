"""Issue 62 item 3: a category is resolved once (``load_category``) and passed down; nothing below the entry point
looks a name up."""

import json
import re

import numpy as np
import pytest

from ancsh.data.category_spec import SpecError
from ancsh.data.conventions import CONVENTIONS
from ancsh.data.generate import FrameGenerator, GenerationConfig
from ancsh.learned.inference.category import DEFAULT_SIZE_RANGE, Category, load_category


@pytest.fixture(scope="module")
def laptop_frame():
    """A noise-free depth image of a held-out open laptop (the test split's frame 2) and its frame."""
    gen = FrameGenerator(GenerationConfig(category="laptop", split="test", seed=0))
    frame = gen.frame(2)
    _, renderer = gen.instance(frame.instance_index)
    return frame, renderer.render(frame.joint_states_abs, frame.T_cam_base, frame.intrinsics).depth


def test_a_loaded_category_holds_its_spec_network_calibrations_and_limits():
    laptop = load_category("laptop")
    conv = CONVENTIONS["laptop"]
    assert laptop.name == "laptop" and laptop.convention is conv
    assert laptop.size_range == conv.diagonal_range and laptop.typical_size == conv.typical_size
    assert laptop.weights_path().is_file() and laptop.weights_path("refine").name == "laptop_refine.pt"
    assert laptop.p_good_calibration["weights_sha256"] and laptop.p_object_calibration["features"]
    assert laptop.names(2, 1) == (("base", "display"), ("display_hinge",))
    assert laptop.names(3, 2) == (("part0", "part1", "part2"), ("joint0", "joint1"))  # another structure
    rest, words = laptop.rest_states(1)
    assert rest == pytest.approx((np.pi / 2,)) and words == conv.rest_description
    assert load_category(laptop) is laptop  # a Category is passed through, not loaded again
    assert laptop.template_library() is laptop.template_library()  # read once, kept


def test_load_category_refuses_unknown_names_and_wrong_specs_and_allows_a_networks_own_name(tmp_path):
    with pytest.raises(FileNotFoundError, match=r"no shipped weights for 'toaster'; available: .*laptop"):
        load_category("toaster")
    own = load_category("toaster", network_category="toaster")  # a network naming a category without a convention
    assert own.convention is None and own.size_range == DEFAULT_SIZE_RANGE and not own.has_templates()
    assert own.rest_states(1)[0] != own.rest_states(1)[0]  # NaN: unknown
    bad = tmp_path / "bad.toml"
    bad.write_text('spec_version = 1\nname = "thing"\ncolour = "red"\n')
    with pytest.raises(SpecError, match="bad.toml: colour"):
        load_category(bad)
    with pytest.raises(ValueError, match="category: expected"):
        load_category(3)


def test_predict_with_a_loaded_category_looks_no_name_up(laptop_frame, monkeypatch):
    """Once loaded (its template read), ``predict_depth`` with the :class:`Category` runs isolation, the network, the
    fit, the checks, the calibrations and render-and-compare without one lookup by name: every lookup is made to fail,
    and the answer is the one of the call given the name."""
    import ancsh.data.conventions as conventions
    import ancsh.data.templates as templates
    import ancsh.learned.inference.confidence as confidence
    import ancsh.learned.network.weights as weights
    from ancsh.learned.inference.predict import predict_depth

    frame, depth = laptop_frame
    options = dict(seed=0, hypotheses=1)
    by_name = predict_depth(depth, frame.intrinsics, "laptop", **options)
    laptop = load_category("laptop")
    laptop.template_library()

    def lookup(*args, **kwargs):
        raise AssertionError(f"a lookup by name below the entry point: {args}")

    registry = type(CONVENTIONS)
    for name in ("__getitem__", "__contains__", "get"):
        monkeypatch.setattr(registry, name, lookup)
    for module, name in ((conventions, "category_folder"), (weights, "weights_dir"), (weights, "weights_path"),
                         (templates, "load_template_library"), (templates, "library_path"),
                         (templates, "refine_default"), (confidence, "calibration_path"),
                         (confidence, "object_calibration_path")):
        monkeypatch.setattr(module, name, lookup)
    loaded = predict_depth(depth, frame.intrinsics, laptop, **options)
    assert loaded.result.ok and loaded.category == "laptop" and loaded.category_info is laptop
    data, expected = (_untimed(p.to_json()) for p in (loaded, by_name))
    assert data == expected
    assert loaded.p_good is not None and loaded.p_object is not None  # the calibrations came from the Category
    monkeypatch.undo()


def test_a_name_with_a_provider_of_that_category_reuses_the_providers_category(laptop_frame, monkeypatch):
    """``predict_depth(..., "laptop", provider=p)`` takes ``p.category_info`` (loaded once, with ``p``) rather than
    reading the calibrations again each call; another category's name is still refused."""
    import ancsh.learned.inference.predict as predict
    from ancsh.learned.inference.predict import make_provider, predict_depth

    frame, depth = laptop_frame
    provider = make_provider("laptop", seed=0)

    def lookup(*args, **kwargs):
        raise AssertionError(f"the category was loaded again: {args}")

    monkeypatch.setattr(predict, "load_category", lookup)
    out = predict_depth(depth, frame.intrinsics, "laptop", provider=provider, seed=0, hypotheses=1)
    assert out.category_info is provider.category_info
    monkeypatch.undo()
    with pytest.raises(ValueError, match="provider: holds a laptop network, not a drawer one"):
        predict_depth(depth, frame.intrinsics, "drawer", provider=provider, seed=0, hypotheses=1)


def _untimed(data) -> str:
    """A prediction's JSON without its times (which differ between two runs of the same prediction)."""
    def strip(x):
        if isinstance(x, dict):
            return {k: strip(v) for k, v in x.items() if not (k.endswith(("_ms", "_s")) or "time" in k)}
        return [strip(v) for v in x] if isinstance(x, list) else x

    return re.sub(r"[0-9.]+ ms", "ms", json.dumps(strip(data), sort_keys=True))


def test_lower_floors_refuse_a_name(laptop_frame):
    """The pieces below take what they need, not a name: a name given to them is refused with a clear error."""
    from ancsh.data.isolate import isolate_object
    from ancsh.learned.inference.candidate import inflate_uncertainty, template_comparison
    from ancsh.learned.inference.confidence import fit_features

    frame, depth = laptop_frame
    with pytest.raises(ValueError, match="size_range: expected \\(lo, hi\\) metres, got the name 'laptop'"):
        isolate_object(depth, frame.intrinsics, "laptop")
    with pytest.raises(ValueError, match="size_range: expected 0 < lo <= hi"):
        isolate_object(depth, frame.intrinsics, (0.6, 0.3))
    with pytest.raises(ValueError, match="typical_size: expected a positive number"):
        fit_features([], "laptop")
    with pytest.raises(ValueError, match="category: expected a Category"):
        template_comparison(None, None, depth, frame.intrinsics, depth > 0, "laptop")
    with pytest.raises(ValueError, match="category: expected a Category"):
        inflate_uncertainty(None, "laptop", None)


def test_trackers_load_the_category_once_and_its_spec_says_whether_the_template_is_carried():
    from ancsh.learned.inference.provider import LearnedProvider
    from ancsh.tracking import CategoryTracker, TrackerConfig

    laptop = load_category("laptop")
    provider = LearnedProvider(laptop.weights_path(), category=laptop)
    assert provider.category_info is laptop and provider.category == "laptop"
    tracker = CategoryTracker(provider, TrackerConfig(), category=laptop)
    assert tracker.category_info is laptop and tracker.category == "laptop"
    assert isinstance(CategoryTracker(provider, category="laptop").category_info, Category)
    default = TrackerConfig()
    assert default.template_categories is None
    carried = {name for name in CONVENTIONS if default.carries_template(CONVENTIONS[name])}
    assert carried == {name for name in CONVENTIONS if CONVENTIONS[name].track_template} == {"laptop"}
    assert not TrackerConfig(template_categories=()).carries_template(CONVENTIONS["laptop"])
    assert TrackerConfig(template_categories=("drawer",)).carries_template(CONVENTIONS["drawer"])
    assert not default.carries_template(None)
    with pytest.raises(ValueError, match="template_categories: expected a tuple of category names or None"):
        TrackerConfig(template_categories="laptop")


def test_a_provider_refuses_a_category_its_network_is_not_of():
    from ancsh.learned.inference.provider import LearnedProvider

    drawer = load_category("drawer")
    with pytest.raises(ValueError, match="category: the network is a drawer network, not a laptop one"):
        LearnedProvider(drawer.weights_path(), category=load_category("laptop"))
    with pytest.raises(ValueError, match="category: expected a Category"):
        LearnedProvider(drawer.weights_path(), category="drawer")
