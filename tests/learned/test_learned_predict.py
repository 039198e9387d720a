"""ancsh predict: depth image files in, result JSON / picture out; error paths."""

import dataclasses
import json
import re
import subprocess
import sys

import numpy as np
import pytest
from PIL import Image

from ancsh.cli import main
from ancsh.data.generate import FrameGenerator, GenerationConfig
from ancsh.learned.inference.predict import depth_to_points, predict_depth, read_depth, read_intrinsics
from ancsh.learned.training.train import Trainer
from ancsh.learned.network.weights import export_weights
from ancsh.outputs import without_timings


@pytest.fixture(scope="module")
def rendered():
    """A noise-free depth image of a held-out, open laptop (test split, display at 83 deg) and its frame."""
    gen = FrameGenerator(GenerationConfig(category="laptop", split="test", seed=0))
    frame = gen.frame(2)  # frame 1, a nearly closed laptop (10 deg), is fitted 52 deg off and rejected (p_object)
    _, renderer = gen.instance(frame.instance_index)
    view = renderer.render(frame.joint_states_abs, frame.T_cam_base, frame.intrinsics)
    return frame, view.depth


@pytest.fixture
def files(tmp_path, rendered):
    """The depth as a 16-bit PNG in millimetres and as .npy in metres, with K.json."""
    frame, depth = rendered
    Image.fromarray(np.round(depth * 1000).astype(np.uint16)).save(tmp_path / "depth.png")
    np.save(tmp_path / "depth.npy", depth)
    (tmp_path / "K.json").write_text(json.dumps(frame.intrinsics.to_json()))
    return tmp_path


@pytest.fixture
def tiny_laptop_weights(tmp_path, tiny_arrays, tiny_config):
    """A randomly initialised tiny two-part, one-revolute-joint network (the laptop structure)."""
    cfg = dataclasses.replace(tiny_config, kind="ancsh")
    trainer = Trainer(cfg, tiny_arrays, None, tmp_path / "run", progress=False)
    return export_weights(trainer.save_checkpoint(tmp_path / "run" / "last.pt"), tmp_path / "tiny.pt")


def test_cli_round_trip_writes_json_and_picture(files, tiny_laptop_weights, rendered):
    frame, _ = rendered
    out, png = files / "result.json", files / "view.png"
    code = main(["predict", "--depth", str(files / "depth.png"), "--intrinsics", str(files / "K.json"),
                 "--category", "laptop", "--weights", str(tiny_laptop_weights), "--points", "256",
                 "--out", str(out), "--png", str(png)])
    assert png.stat().st_size > 0
    data = json.loads(out.read_text())
    assert code == (0 if data["ok"] else 1)  # a failed status exits non-zero
    assert data["points"] == 256 and data["valid_pixels"] > 256
    assert data["status"] in {"success", "max_iter", "infeasible", "numerical_failure", "too_few_points", "degenerate",
                              "implausible_size", "too_few_inliers", "large_residual", "no_object",
                              "not_this_category", "out_of_view"}
    assert [p["name"] for p in data["parts"]] == list(frame.part_names)
    assert [j["name"] for j in data["joints"]] == list(frame.joint_names)
    assert data["input"]["intrinsics"] == frame.intrinsics.to_json()
    if data["ok"]:
        for part in data["parts"]:
            assert np.shape(part["pose"]["rotation"]) == (3, 3) and np.shape(part["pose"]["translation"]) == (3,)
            assert np.shape(part["box"]["corners"]) == (8, 3) and np.shape(part["box"]["extents"]) == (3,)
        assert np.shape(data["joints"][0]["axis_cam"]) == (3,) and data["joints"][0]["state_unit"] == "rad"
        unc = data["uncertainty"]
        assert unc["inflation"]["source"] == "raw"  # weights other than the shipped ones: no measured factors
        assert len(unc["parts"]) == len(data["parts"]) and len(unc["joints"]) == len(data["joints"])
    assert set(data["timings_ms"]) == {"isolate", "verify", "backproject", "network", "fit", "render_compare", "total"}


def test_shipped_weights_prediction_is_a_successful_fit_of_the_object(files, rendered):
    frame, depth = rendered
    depth, intrinsics = read_depth(files / "depth.png"), read_intrinsics(files / "K.json")
    from ancsh.solvers.uncertainty import inflation_for

    refined = predict_depth(depth, intrinsics, "laptop", refine="template").to_json()
    assert refined["ok"]
    if "(articulated" in refined["message"]:  # the template ICP's covariance, with the factors measured for such fits
        unc = refined["uncertainty"]
        expected = inflation_for("learned-template", "laptop", weights_sha256=refined["weights_sha256"]).source
        assert unc["status"] == "ok" and unc["inflation"]["source"] == expected
        assert all(p["scale_std"] is None or p["scale_std"] != p["scale_std"] for p in unc["parts"])  # not estimated
    elif "category template" in refined["message"]:  # the base candidate: no covariance (docs/json_schema.md)
        assert refined["uncertainty"] is None
    by_network = predict_depth(depth, intrinsics, "laptop", refine="network").to_json()
    assert by_network["ok"] and "refinement network: kept" in " ".join(by_network.get("notes", [])) + by_network["message"]
    # the refiner's fits carry the factors measured for them and that refiner (raw where none were measured)
    from ancsh.learned.network.weights import weights_path
    from ancsh.outputs import file_sha256

    expected = inflation_for("learned-network", "laptop", weights_sha256=file_sha256(weights_path("laptop", "refine"))).source
    assert by_network["uncertainty"]["inflation"]["source"] == expected
    pred = predict_depth(depth, intrinsics, "laptop", refine="none")
    data = pred.to_json()
    assert data["ok"] and data["formulation"] == "exact_reduced"
    # the shipped weights' standard deviations carry the measured inflation (raw ones beside them)

    unc, inflation = data["uncertainty"], inflation_for("learned", "laptop", weights_sha256=data["weights_sha256"])
    assert unc["inflation"]["source"] == inflation.source == "learned/laptop"
    raw = pred.result.uncertainty.raw()
    assert unc["raw"]["joints"][0]["state_std"] == pytest.approx(raw.joint_state_std[0])
    assert unc["joints"][0]["state_std"] == pytest.approx(raw.inflated(inflation).joint_state_std[0])
    assert unc["joints"][0]["state_std"] > unc["raw"]["joints"][0]["state_std"]  # the raw sigmas are over-confident
    # every part box centre lies within the observed cloud's extent (grown by its diagonal)
    lo, hi = pred.points_cam.min(0), pred.points_cam.max(0)
    diag = np.linalg.norm(hi - lo)
    for part in data["parts"]:
        c = np.array(part["box"]["center"])
        assert np.all(c > lo - diag) and np.all(c < hi + diag)


def test_png_and_npy_give_the_same_points_on_the_depth_rays(files, rendered):
    frame, depth = rendered
    intr = read_intrinsics(files / "K.json")
    a, pix, valid = depth_to_points(read_depth(files / "depth.png"), intr, num_points=300, rng=4)
    b, pix_b, _ = depth_to_points(read_depth(files / "depth.npy"), intr, num_points=300, rng=4)
    np.testing.assert_array_equal(pix, pix_b)
    np.testing.assert_allclose(a, b, atol=1e-3)  # millimetre quantisation of the PNG
    u, v = pix[:, 0], pix[:, 1]
    np.testing.assert_allclose(b[:, 2], depth[v, u])
    np.testing.assert_allclose(b[:, 0], (u - intr.cx) / intr.fx * depth[v, u])
    assert valid == np.count_nonzero(depth > 0) and len(np.unique(pix, axis=0)) == 300
    # max depth and mask select pixels
    cut = float(np.median(depth[depth > 0]))
    c, _, n_cut = depth_to_points(depth, intr, max_depth=cut, num_points=None)
    assert n_cut == np.count_nonzero((depth > 0) & (depth <= cut)) and np.all(c[:, 2] <= cut)


def test_error_paths(files, rendered, tmp_path, capsys):
    frame, depth = rendered
    intr = read_intrinsics(files / "K.json")
    with pytest.raises(FileNotFoundError, match="depth: no such file"):
        read_depth(files / "missing.png")
    assert main(["predict", "--depth", str(files / "missing.png"), "--intrinsics", str(files / "K.json"),
                 "--category", "laptop"]) == 2
    assert "no such file" in capsys.readouterr().err
    with pytest.raises(ValueError, match="no valid pixel"):
        depth_to_points(depth, intr, mask=np.zeros(depth.shape, dtype=bool))
    with pytest.raises(ValueError, match="no valid pixel"):
        depth_to_points(np.zeros_like(depth), intr)
    with pytest.raises(ValueError, match="does not match"):
        depth_to_points(depth[:-1], intr)
    Image.fromarray(np.zeros((4, 4), dtype=np.uint8)).save(tmp_path / "eight.png")
    with pytest.raises(ValueError, match="16-bit"):
        read_depth(tmp_path / "eight.png")
    np.save(tmp_path / "rgb.npy", np.zeros((4, 4, 3)))
    with pytest.raises(ValueError, match="2-D"):
        read_depth(tmp_path / "rgb.npy")
    (tmp_path / "bad.json").write_text(json.dumps({"fx": 1.0}))
    with pytest.raises(ValueError, match="intrinsics"):
        read_intrinsics(tmp_path / "bad.json")
    with pytest.raises(FileNotFoundError, match=r"no shipped weights for 'toaster'; available: .*laptop"):
        predict_depth(depth, intr, "toaster")
    Image.fromarray(np.zeros((3, 3), dtype=np.uint8)).save(tmp_path / "mask.png")
    assert main(["predict", "--depth", str(files / "depth.png"), "--intrinsics", str(files / "K.json"),
                 "--category", "laptop", "--mask", str(tmp_path / "mask.png")]) == 2
    assert "mask: expected shape" in capsys.readouterr().err


def test_refine_passes_reach_the_refinement_network(files, rendered):
    """``--refine-passes N``: up to N passes of the shipped refinement network (its note lists one rotation change per
    pass run; the default runs DEFAULT_PASSES); without ``--refine network`` the option is refused before any work."""
    from ancsh.learned.inference.refine_network import DEFAULT_PASSES

    def passes_run(*extra):
        out = files / "refined.json"
        r = subprocess.run([sys.executable, "-m", "ancsh", "predict", "--depth", str(files / "depth.npy"), "--intrinsics",
                            str(files / "K.json"), "--category", "laptop", "--refine", "network", *extra,
                            "--out", str(out)], capture_output=True, text=True)
        assert r.returncode == 0, r.stderr
        notes = [n for n in json.loads(out.read_text())["notes"] if n.startswith("refinement network")]
        assert len(notes) == 1, notes
        moved = re.search(r"rotation moved ([0-9., ]+) deg per pass", notes[0])
        return len(moved.group(1).split(",")), notes[0]

    n_default, note = passes_run()
    assert n_default <= DEFAULT_PASSES, note
    n3, note = passes_run("--refine-passes", "3")
    assert n3 > DEFAULT_PASSES or "converged" in note, note
    r = subprocess.run([sys.executable, "-m", "ancsh", "predict", "--depth", str(files / "depth.npy"), "--intrinsics",
                        str(files / "K.json"), "--category", "laptop", "--refine-passes", "1", "--out",
                        str(files / "x.json")], capture_output=True, text=True)
    assert r.returncode == 2 and "--refine-passes" in r.stderr and "Traceback" not in r.stderr


def _poses(candidate) -> np.ndarray:
    """(M, 4, 4) NPCS -> camera matrices of a candidate's fit."""
    return np.stack([T.matrix() for T in candidate["result"].T_cam_npcs])


def test_refinements_sharing_the_first_stage_give_each_refinements_own_fit(rendered):
    """``fit_candidate_refinements`` runs the network and the first-stage fit once for several refinements: each
    refinement's fit and evidence are those of its own ``fit_candidate`` (in another order, so that a refinement that
    changed the shared first stage would show)."""
    from ancsh.learned.inference.candidate import fit_candidate, fit_candidate_refinements
    from ancsh.learned.inference.category import load_category
    from ancsh.learned.inference.provider import LearnedProvider

    frame, depth = rendered
    provider = LearnedProvider("laptop", seed=0)
    options = ("template", "none", "network")
    args = (depth, frame.intrinsics, depth > 0, load_category("laptop"), provider, "exact_reduced", 1024, 3, None)
    shared = fit_candidate_refinements(*args, options, object_gate=False)
    alone = {r: fit_candidate(*args, r, object_gate=False, hypotheses=1) for r in reversed(options)}
    assert len(shared) == len(options)
    for refine, a in zip(options, shared):
        b = alone[refine]
        assert a["result"].status == b["result"].status and a["result"].ok, refine
        np.testing.assert_allclose(_poses(a), _poses(b), atol=1e-9, err_msg=refine)
        np.testing.assert_allclose(a["result"].joint_states, b["result"].joint_states, atol=1e-9, err_msg=refine)
        np.testing.assert_array_equal(a["labels"], b["labels"])
        untimed = [[re.sub(r"[0-9.]+ ms", "ms", n) for n in c["notes"]] for c in (a, b)]
        assert untimed[0] == untimed[1] and a["p_good"] == b["p_good"]
        assert (a["comparison"] is None) == (b["comparison"] is None)
    # the three refinements are not one fit three times
    t = [_poses(a) for a in shared]
    assert not np.allclose(t[0], t[1]) and not np.allclose(t[1], t[2])
    with pytest.raises(ValueError, match="refinements"):
        fit_candidate_refinements(*args, ())
    with pytest.raises(ValueError, match="category: expected a Category"):  # a name is resolved once, by the caller
        fit_candidate_refinements(*args[:3], "laptop", *args[4:], options)


def test_a_folder_gives_the_same_files_with_one_and_two_workers(files, rendered, capsys):
    """``--workers 2``: two processes, each loading the network once; every image's JSON as with one worker."""
    frames = files / "frames"
    frames.mkdir()
    depth = read_depth(files / "depth.png")
    for i, shift in enumerate((0.0, 0.05, 0.1)):  # the laptop nearer and farther
        np.save(frames / f"f{i}.npy", np.where(depth > 0, depth + shift, 0.0))
    results = {}
    for workers in (1, 2):
        out = files / f"out{workers}"
        code = main(["predict", "--depth", str(frames), "--intrinsics", str(files / "K.json"), "--category", "laptop",
                     "--hypotheses", "1", "--workers", str(workers), "--out", str(out)])
        assert code in (0, 1) and "3 images" in capsys.readouterr().out.replace("of 3 images", "3 images")
        results[workers] = {p.name: json.loads(p.read_text()) for p in sorted(out.glob("*.json"))}
    assert sorted(results[1]) == ["f0.json", "f1.json", "f2.json"]
    for name in results[1]:
        assert without_timings(results[1][name]) == without_timings(results[2][name])
    assert main(["predict", "--depth", str(files / "depth.png"), "--intrinsics", str(files / "K.json"), "--category",
                 "laptop", "--workers", "2"]) == 2
    assert "--workers: one image is predicted in one process" in capsys.readouterr().err


def test_predict_fits_with_the_shipped_networks_default_objective(rendered, monkeypatch):
    """Issue 63: every fit of ``ancsh predict`` -- the first stage and the refinement network's -- uses the objective
    that ``DEFAULT_OBJECTIVES["learned"]`` names for the category (``LearnedProvider.fit_config``), not the plain
    ``FitConfig()`` default; the figures behind both are in the table."""
    import ancsh.solvers
    from ancsh.learned.inference.provider import LearnedProvider
    from ancsh.solvers import FitConfig
    from ancsh.solvers.formulations import default_objective

    chosen = default_objective("learned", "laptop")
    assert LearnedProvider("laptop").fit_config() == FitConfig.default_for("learned", "laptop")
    assert LearnedProvider("laptop").fit_config().objective is chosen
    frame, depth = rendered
    seen = []
    real_fit = ancsh.solvers.fit

    def spy(observation, correspondences, formulation="exact_reduced", solver=None, config=None, *args, **kwargs):
        seen.append(config)
        return real_fit(observation, correspondences, formulation, solver, config, *args, **kwargs)

    monkeypatch.setattr(ancsh.solvers, "fit", spy)
    assert predict_depth(depth, frame.intrinsics, "laptop", refine="network").to_json()["ok"]
    assert len(seen) >= 2 and all(c is not None and c.objective is chosen for c in seen), seen
