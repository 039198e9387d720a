"""The refinement network on pose-canonicalised input (TrainConfig.refine_perturb_deg, refine="network")."""

import dataclasses
import subprocess
import sys

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from ancsh.geometry.rotations import rotation_angle
from ancsh.learned.inference.provider import LearnedProvider
from ancsh.learned.inference.refine_network import DEFAULT_PASSES, refine_with_network
from ancsh.learned.network.config import TrainConfig
from ancsh.learned.network.weights import load_network, weights_path
from ancsh.learned.training.data import stack_frames
from ancsh.learned.training.train import Trainer, input_batch, refine_rotations
from ancsh.solvers import Observation, fit


def _frames(seed, n, *, num_parts=2):
    from ancsh.model.canonical import ancsh_ground_truth
    from ancsh.model.synthetic import random_articulated_model, sample_frame

    rng = np.random.default_rng(seed)
    model = random_articulated_model(rng, num_parts=num_parts, joint_types="revolute")
    out = []
    for _ in range(n):
        fr = sample_frame(model, rng, points_per_part=80)
        out.append((fr.points_cam, ancsh_ground_truth(model, fr.q, fr.T_cam_base, fr.points_cam, fr.part_labels)))
    return out


def test_naocs_rotations_recover_the_true_orientation():
    pairs = _frames(11, 4, num_parts=3)
    arrays = stack_frames(pairs, 128, 0)
    R = arrays.naocs_rotations(np.arange(4))
    for b, (_, gt) in enumerate(pairs):
        assert np.degrees(rotation_angle(R[b].T @ gt.T_cam_naocs.rotation)) < 1e-4  # float32 arrays


def test_refine_rotations_perturb_within_the_bound_and_are_seeded():
    R_true = Rotation.random(200, random_state=1).as_matrix()
    seeds = [[0, 1, i] for i in range(200)]
    out = refine_rotations(R_true, np.radians(15.0), seeds)
    angles = np.array([np.degrees(rotation_angle(out[b] @ R_true[b])) for b in range(200)])  # the perturbation dR
    assert angles.max() <= 15.0 + 1e-9 and angles.max() > 12.0 and angles.min() < 3.0
    assert np.array_equal(out, refine_rotations(R_true, np.radians(15.0), seeds))
    assert not np.allclose(out, refine_rotations(R_true, np.radians(15.0), [[0, 2, i] for i in range(200)]))


def test_a_refiner_sees_its_frames_in_the_perturbed_naocs_orientation(tiny_config):
    from ancsh.geometry.umeyama import umeyama_batch

    pairs = _frames(12, 3)
    arrays = stack_frames(pairs, 64, 0)
    config = dataclasses.replace(tiny_config, refine_perturb_deg=10.0)
    points, targets = input_batch(arrays, np.arange(3), config, [[0, 0, i] for i in range(3)])
    naocs = arrays.scale[..., None] * arrays.npcs + arrays.translation
    R, _, _, _ = umeyama_batch(naocs.astype(float), points.numpy().astype(float),
                               (arrays.labels == arrays.root_part).astype(float))
    angles = [np.degrees(rotation_angle(r)) for r in R]
    assert max(angles) <= 10.0 + 1e-3  # float32 points
    assert np.array_equal(targets.npcs.numpy(), arrays.npcs[:3])  # canonical targets are unchanged
    first, _ = input_batch(arrays, np.arange(3), tiny_config, [[0, 0, i] for i in range(3)])
    assert np.array_equal(first.numpy(), arrays.points[:3])  # a first-stage network sees the camera frame


def test_a_refiner_trains_and_validates(tiny_config):
    arrays = stack_frames(_frames(13, 6), 64, 0)
    config = dataclasses.replace(tiny_config, refine_perturb_deg=15.0, max_steps=3, val_every=3)
    tr = Trainer(config, arrays, arrays, progress=False)
    tr.fit()
    row = tr.history[-1]
    assert row["step"] == 3 and np.isfinite(row["val_npcs_err"]) and np.isfinite(row["train_total"])


@pytest.mark.parametrize("change, match", [
    (dict(refine_perturb_deg=-1.0), "refine_perturb_deg"),
    (dict(refine_perturb_deg=91.0), "refine_perturb_deg"),
    (dict(refine_perturb_deg=True), "refine_perturb_deg"),
    (dict(refine_perturb_deg=10.0, kind="direct_voting"), "ANCSH network"),
    (dict(refine_perturb_deg=10.0, augment_roll_deg=5.0), "augment_roll_deg"),
])
def test_refiner_settings_are_checked(change, match):
    with pytest.raises(ValueError, match=match):
        TrainConfig(**change)
    assert TrainConfig(refine_perturb_deg=10).is_refiner and not TrainConfig().is_refiner


def test_a_refiner_without_an_input_rotation_is_refused(tmp_path, make_refiner):
    p = LearnedProvider(str(make_refiner()))
    obs = Observation(np.random.default_rng(0).normal(size=(200, 3)) * 0.1 + [0, 0, 1])
    with pytest.raises(ValueError, match="input_rotation: .*refinement network"):
        p.correspond(obs)
    with pytest.raises(ValueError, match="input_rotation: expected a"):
        p.correspond(obs, input_rotation=np.diag([1.0, 1.0, -1.0]))
    assert p.correspond(obs, input_rotation=np.eye(3)).num_points == 200


def test_refiner_choice_is_checked(tmp_path, make_refiner):
    with pytest.raises(ValueError, match="refiner: .*first-stage"):
        LearnedProvider("laptop", refine="network", refiner="laptop")
    with pytest.raises(ValueError, match="refiner: .*refine='network' only"):
        LearnedProvider("laptop", refine="template", refiner=str(make_refiner()))
    with pytest.raises(ValueError, match="refiner: .*predicts 2 parts"):
        LearnedProvider("drawer", refine="network", refiner=str(make_refiner()))
    if not weights_path("laptop", "refine").is_file():
        with pytest.raises(FileNotFoundError, match="no refinement network is shipped for 'laptop'"):
            LearnedProvider("laptop", refine="network")


def _laptop_frame():
    from ancsh.data.generate import FrameGenerator, GenerationConfig

    return FrameGenerator(GenerationConfig(category="laptop", split="test", seed=0)).frame(2)  # an open laptop (83 deg)


def test_network_refinement_commutes_with_a_camera_rotation(tmp_path, make_refiner):
    """The refiner's input is the points in the first fit's NAOCS orientation, so rotating the camera (points and
    first fit alike) leaves its input unchanged and rotates the refined fit with it."""
    fr = _laptop_frame()
    p = LearnedProvider("laptop", refine="network", refiner=str(make_refiner()))
    obs = Observation(fr.points)
    corr = p.correspond(obs)
    Q = Rotation.from_rotvec([0.3, -0.2, 0.5]).as_matrix()
    obs_q = Observation(fr.points @ Q.T)
    first, first_q = fit(obs, corr, "exact_reduced", rng=0), fit(obs_q, corr, "exact_reduced", rng=0)
    ref = refine_with_network(p.refiner, obs, first, passes=2, rng=0)
    ref_q = refine_with_network(p.refiner, obs_q, first_q, passes=2, rng=0)
    assert ref.accepted and ref_q.accepted and ref.passes == ref_q.passes
    assert np.array_equal(ref.inference.correspondences.part_labels, ref_q.inference.correspondences.part_labels)
    for T, T_q in zip(ref.result.T_cam_npcs, ref_q.result.T_cam_npcs):
        assert np.degrees(rotation_angle(T_q.rotation.T @ Q @ T.rotation)) < 0.05
        assert np.linalg.norm(T_q.translation - Q @ T.translation) < 1e-4
    assert np.allclose(ref.result.joint_states, ref_q.result.joint_states, atol=1e-3)
    # one change per successful pass; a pass whose fit failed ends the refinement and says so
    assert len(ref.rotation_change_deg) == ref.passes or (
        len(ref.rotation_change_deg) == ref.passes - 1 and "the fit failed" in ref.reason) or not ref.accepted


def test_network_refinement_of_a_failed_fit_is_refused(tmp_path, make_refiner):
    from ancsh.solvers.types import FitResult, FitStatus

    p = LearnedProvider("laptop", refine="network", refiner=str(make_refiner()))
    failed = FitResult.failure(FitStatus.TOO_FEW_POINTS, "x", formulation="exact_reduced", solver="none", num_joints=1,
                               num_points=10)
    with pytest.raises(ValueError, match="fit_result"):
        refine_with_network(p.refiner, Observation(np.ones((10, 3)) + np.arange(10)[:, None]), failed)
    with pytest.raises(ValueError, match="passes"):
        refine_with_network(p.refiner, Observation(_laptop_frame().points), failed, passes=0)
    with pytest.raises(ValueError, match="first-stage"):
        refine_with_network(LearnedProvider("laptop"), Observation(_laptop_frame().points), failed)


def test_evaluate_adds_the_refinement_network_row(tmp_path, make_refiner):
    from ancsh.studies.table1 import evaluate_category, summarize

    ev = evaluate_category("laptop", frames=2, methods=("exact_reduced",), refine="network",
                           refiner=make_refiner(), progress=False)
    assert ev["settings"]["methods"] == ["exact_reduced", "network"]
    assert ev["settings"]["refiner"].endswith("laptop_refine.pt")
    refiner = load_network(make_refiner())
    assert (ev["settings"]["refiner_step"], ev["settings"]["refiner_sha256"]) == (refiner.step, refiner.sha256)
    from ancsh.studies.table1.report import _weights_line

    passes = f"{DEFAULT_PASSES} pass{'es' if DEFAULT_PASSES > 1 else ''}"
    assert f"refinement network: `laptop_refine.pt` (step {refiner.step}, sha256 {refiner.sha256[:12]}, {passes})" in \
        _weights_line(ev["settings"])
    assert ev["settings"]["refine_passes"] == DEFAULT_PASSES
    rec = ev["records"][0]["methods"]["network"]
    assert rec["network_refine"]["passes"] >= 1
    assert "network" in summarize(ev)["methods"]
    three = evaluate_category("laptop", frames=2, methods=("exact_reduced",), refine="network", refiner=make_refiner(),
                              refine_passes=3, progress=False)
    assert three["settings"]["refine_passes"] == 3 and "3 passes)" in _weights_line(three["settings"])
    ran = [r["methods"]["network"]["network_refine"]["passes"] for r in three["records"]]
    assert max(ran) <= 3 and (max(ran) > DEFAULT_PASSES or DEFAULT_PASSES >= 3), ran  # the option reached the passes
    with pytest.raises(ValueError, match="refiner"):
        evaluate_category("laptop", frames=1, refiner=make_refiner(), progress=False)
    for bad in (0, 1.5, True):
        with pytest.raises(ValueError, match="refine_passes"):
            evaluate_category("laptop", frames=1, refine="network", refiner=make_refiner(), refine_passes=bad, progress=False)
    with pytest.raises(ValueError, match="refine_passes"):
        evaluate_category("laptop", frames=1, refine_passes=1, progress=False)


def test_cli_refiner_needs_refine_network(tmp_path, make_refiner):
    r = subprocess.run([sys.executable, "-m", "ancsh", "evaluate", "--category", "laptop", "--frames", "1",
                        "--refiner", str(make_refiner()), "--out", str(tmp_path / "o")],
                       capture_output=True, text=True)
    assert r.returncode == 2 and "--refiner" in r.stderr and "Traceback" not in r.stderr
    r = subprocess.run([sys.executable, "-m", "ancsh", "evaluate", "--category", "laptop", "--frames", "1",
                        "--refine-passes", "1", "--out", str(tmp_path / "o")], capture_output=True, text=True)
    assert r.returncode == 2 and "--refine-passes" in r.stderr and "Traceback" not in r.stderr


def test_refiner_is_loaded_as_an_ancsh_network(tmp_path, make_refiner):
    net = load_network(make_refiner())
    assert net.kind == "ancsh" and net.config.is_refiner


def test_predict_refines_with_the_network_and_keeps_its_correspondences(tmp_path, make_refiner):
    from ancsh.learned.inference.predict import predict_depth

    gen_frame = _laptop_frame()
    from ancsh.data.generate import FrameGenerator, GenerationConfig

    gen = FrameGenerator(GenerationConfig(category="laptop", split="test", seed=0))
    _, renderer = gen.instance(gen_frame.instance_index)
    depth = renderer.render(gen_frame.joint_states_abs, gen_frame.T_cam_base, gen_frame.intrinsics).depth
    mask = depth > 0
    pred = predict_depth(depth, gen_frame.intrinsics, "laptop", mask=mask, refine="network")  # the shipped refiner
    assert any(n.startswith("refinement network: kept") for n in pred.notes), pred.notes
    assert pred.result.ok
    with pytest.raises(ValueError, match="refiner"):
        predict_depth(depth, gen_frame.intrinsics, "laptop", mask=mask, refine="template", refiner=make_refiner())
