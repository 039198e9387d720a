"""Multi-object tracking: the state filter, the assignment, the filtered model, the support plane, rendered scene
sequences, and the tracker with the shipped network on them."""

from __future__ import annotations

import itertools
import json

import numpy as np
import pytest

from ancsh.geometry.rotations import exp_so3, geodesic_angle
from ancsh.tracking.association import associate
from ancsh.tracking.state_filter import StateFilter, StateFilterConfig


# --------------------------------------------------------------------------------------------
# the state filter
# --------------------------------------------------------------------------------------------

def _noisy(rng, R, t, q, rot_sigma, t_sigma, q_sigma):
    return exp_so3(rng.normal(0, rot_sigma, 3)) @ R, t + rng.normal(0, t_sigma, 3), q + rng.normal(0, q_sigma, len(q))


def test_filter_of_a_still_object_is_closer_to_the_truth_than_its_measurements():
    """Scenario: a still object measured 60 times with seeded noise at the filter's own measurement noise: the
    filtered state ends nearer the truth than the mean single measurement, and its reported standard deviations
    shrink below a measurement's."""
    rng = np.random.default_rng(3)
    cfg = StateFilterConfig()
    R, t, q = exp_so3(np.array([0.3, -0.2, 0.1])), np.array([0.1, -0.05, 1.2]), np.array([1.0, 0.2])
    f = StateFilter(("revolute", "prismatic"), config=cfg)
    raw_q, raw_rot, raw_t, out_q, out_rot, out_t = [], [], [], [], [], []
    for i in range(60):
        f.predict()
        Rm, tm, qm = _noisy(rng, R, t, q, cfg.rotation_std, cfg.translation_std, [cfg.revolute_floor, cfg.prismatic_floor])
        f.update(Rm, tm, qm)
        if i >= 20:  # after the start
            raw_q.append(np.abs(qm - q))
            raw_rot.append(geodesic_angle(Rm, R))
            raw_t.append(np.linalg.norm(tm - t))
            out_q.append(np.abs(f.joint_states - q))
            out_rot.append(geodesic_angle(f.R, R))
            out_t.append(np.linalg.norm(f.translation - t))
    assert np.all(np.mean(out_q, axis=0) < 0.75 * np.mean(raw_q, axis=0))
    assert np.mean(out_rot) < 0.75 * np.mean(raw_rot) and np.mean(out_t) < 0.75 * np.mean(raw_t)
    assert np.all(f.joint_states_std < [cfg.revolute_floor, cfg.prismatic_floor])


def test_filter_follows_a_constant_velocity_without_lag():
    """A joint opening at a constant 2 deg per frame (noise-free): after 30 frames the filter is on it."""
    f = StateFilter(("revolute",))
    R, t = np.eye(3), np.zeros(3)
    for i in range(30):
        f.predict()
        f.update(R, t, [np.deg2rad(2.0) * i])
    f.predict()
    assert abs(np.rad2deg(f.joint_states[0]) - 60.0) < 0.3


def test_filter_gates_an_outlier_and_restarts_after_several():
    """One measurement 40 deg away is gated (the state stays); ``max_outliers`` of them in a row restart it."""
    cfg = StateFilterConfig(max_outliers=3)
    f = StateFilter(("revolute",), config=cfg)
    for _ in range(10):
        f.predict()
        f.update(np.eye(3), np.zeros(3), [0.5])
    far = 0.5 + np.deg2rad(40)
    f.predict()
    u = f.update(np.eye(3), np.zeros(3), [far])
    assert u.outlier and not u.applied and abs(f.joint_states[0] - 0.5) < 1e-3
    f.predict()
    assert not f.update(np.eye(3), np.zeros(3), [far]).applied
    f.predict()
    u = f.update(np.eye(3), np.zeros(3), [far])
    assert u.applied and u.restarted and abs(f.joint_states[0] - far) < 1e-9


def test_filter_keeps_joint_states_in_their_range():
    """Measurements beyond a bound end at the bound, with no velocity carrying it further."""
    f = StateFilter(("revolute",), limits=[[0.0, 1.0]], config=StateFilterConfig(gate=1e6))
    for q in np.linspace(0.8, 1.4, 12):
        f.predict()
        f.update(np.eye(3), np.zeros(3), [q])
        assert 0.0 <= f.joint_states[0] <= 1.0
    for _ in range(5):
        f.predict()
        f.coast()
    assert f.joint_states[0] == pytest.approx(1.0)


def test_filter_refuses_bad_settings():
    with pytest.raises(ValueError, match="gate"):
        StateFilterConfig(gate=0.0)
    with pytest.raises(ValueError, match="joint_types"):
        StateFilter(("hinge",))
    with pytest.raises(ValueError, match="limits"):
        StateFilter(("revolute",), limits=[[0, 1], [0, 1]])


# --------------------------------------------------------------------------------------------
# the assignment
# --------------------------------------------------------------------------------------------

def test_association_is_the_least_cost_matching_within_the_gates():
    """Against brute force on seeded random costs with forbidden pairs: the same total cost, no forbidden pair."""
    rng = np.random.default_rng(5)
    for trial in range(30):
        T, D = (int(v) for v in rng.integers(1, 5, 2))
        c = rng.random((T, D))
        c[rng.random((T, D)) < 0.3] = np.inf
        pairs = associate(c)
        assert all(np.isfinite(c[i, j]) for i, j in pairs)
        assert len({i for i, _ in pairs}) == len(pairs) == len({j for _, j in pairs})
        best_n, best_cost = 0, 0.0
        for perm in itertools.permutations(range(max(T, D)), T):
            chosen = [(i, j) for i, j in enumerate(perm) if j < D and np.isfinite(c[i, j])]
            n, cost = len(chosen), sum(c[i, j] for i, j in chosen)
            if n > best_n or (n == best_n and cost < best_cost - 1e-12):
                best_n, best_cost = n, cost
        assert len(pairs) == best_n and sum(c[i, j] for i, j in pairs) == pytest.approx(best_cost)
    assert associate(np.zeros((0, 3))) == [] and associate(np.full((2, 2), np.inf)) == []
    with pytest.raises(ValueError, match="cost"):
        associate(np.array([[np.nan]]))


# --------------------------------------------------------------------------------------------
# the filtered model and the support plane
# --------------------------------------------------------------------------------------------

@pytest.mark.parametrize("category", ["laptop", "drawer", "eyeglasses"])
def test_filtered_fit_is_the_fitted_model_at_another_state(category):
    """Scenario: an exact fit of a noise-free frame moved to other joint states and another root pose is the ground
    truth of the same instance at those states and that pose (every part, every joint), to 1e-9."""
    from ancsh.data.generate import FrameGenerator, GenerationConfig
    from ancsh.data.noise import DepthNoise
    from ancsh.evaluation import evaluate_fit
    from ancsh.geometry.transforms import Sim3
    from ancsh.model.canonical import ancsh_ground_truth
    from ancsh.solvers.fit import fit
    from ancsh.solvers.types import Correspondences, Observation
    from ancsh.tracking.multi import filtered_fit

    gen = FrameGenerator(GenerationConfig(category=category, split="test", seed=1, num_points=512, noise=DepthNoise.off()))
    fr = gen.frame(0)
    corr = Correspondences.from_ground_truth(fr.gt)
    res = fit(Observation(fr.points), corr, rng=0)
    model, _ = gen.instance(fr.instance_index)
    rng = np.random.default_rng(2)
    lo, hi = model.lower_limits, model.upper_limits
    q2 = lo + rng.uniform(0.2, 0.8, len(lo)) * (hi - lo)
    motion = Sim3(exp_so3(np.array([0.1, -0.2, 0.05])), np.array([0.05, 0.02, -0.1]))
    T_cam_base2 = motion @ fr.T_cam_base
    truth = ancsh_ground_truth(model, q2, T_cam_base2, fr.points, fr.gt.part_labels)
    root = res.T_cam_npcs[corr.root_part]
    moved = filtered_fit(res, corr, motion.rotation @ root.rotation, motion.apply(root.translation),
                         np.asarray(res.joint_states) + (q2 - np.asarray(fr.joint_states_abs)))
    e = evaluate_fit(moved, truth)
    assert max(p.rot_deg for p in e.parts) < 1e-6 and max(p.trans for p in e.parts) < 1e-9
    assert max(j.state_err for j in e.joints) < 1e-6 and max(j.axis_deg for j in e.joints) < 1e-6


def test_support_height_finds_the_table_and_not_a_flat_part():
    """Points of a table plane (tilted 10 deg from the predicted up) and of a thin flat slab on it: the heights are
    measured from the table, not from the slab's top, when the slab lies inside the fitted boxes."""
    from ancsh.tracking.multi import support_height

    rng = np.random.default_rng(0)
    up = np.array([0.0, -1.0, 0.0])  # camera y points down
    tilt = exp_so3(np.array([0.0, 0.0, np.deg2rad(10.0)]))
    table_up = tilt @ up
    u, v = np.linalg.svd(table_up[None])[2][1:]
    xy = rng.uniform(-0.4, 0.4, (3000, 2))
    table = xy[:, :1] * u + xy[:, 1:] * v + np.array([0.0, 0.3, 1.0])
    slab_xy = rng.uniform(-0.1, 0.1, (3000, 2))
    slab = slab_xy[:, :1] * u + slab_xy[:, 1:] * v + np.array([0.0, 0.3, 1.0]) + 0.02 * table_up
    pts = np.concatenate([table, slab])
    around = np.r_[np.abs(xy).max(axis=1) > 0.12, np.zeros(len(slab), bool)]
    bottom = float(np.array([0.0, 0.3, 1.0]) @ up)
    h = support_height(pts, up, bottom, 0.4, np.random.default_rng(1), around=around)
    assert np.percentile(np.abs(h[: len(table)]), 95) < 0.002
    assert np.median(h[len(table):]) == pytest.approx(0.02, abs=0.002)


# --------------------------------------------------------------------------------------------
# rendered scene sequences
# --------------------------------------------------------------------------------------------

def test_scene_sequence_truth_moves_as_planned():
    """Object 0 opens and closes, the others stay; the occluder covers pixels on some frames only; the translucent
    object loses depth; every frame is a function of the seed; bad settings name their field."""
    from ancsh.data.scene_sequences import SceneSequenceConfig, render_scene_sequence

    cfg = SceneSequenceConfig("laptop", objects=2, length=12, translucent=1, occluder_share=0.3)
    frames = list(render_scene_sequence(cfg, 0))
    q0 = np.array([f.objects[0].q for f in frames])
    q1 = np.array([f.objects[1].q for f in frames])
    assert np.ptp(q0, axis=0).max() > 0.1 and np.ptp(q1, axis=0).max() == 0.0
    occluded = [int(f.occluded.sum()) for f in frames]
    assert max(occluded) > 0 and min(occluded) == 0
    assert all(f.objects[0].visible.sum() > 300 for f in frames)
    again = next(iter(render_scene_sequence(cfg, 0)))
    assert np.array_equal(again.depth, frames[0].depth)
    empty = next(iter(render_scene_sequence(SceneSequenceConfig("laptop", objects=0, length=2), 0)))
    assert empty.objects == () and (empty.depth > 0).mean() > 0.5
    with pytest.raises(ValueError, match="objects"):
        SceneSequenceConfig("laptop", objects=4)
    with pytest.raises(ValueError, match="translucent"):
        SceneSequenceConfig("laptop", objects=2, translucent=2)


# --------------------------------------------------------------------------------------------
# the tracker with the shipped network
# --------------------------------------------------------------------------------------------

def test_multi_object_tracker_follows_two_laptops_with_stable_ids():
    """Scenario: two laptops (one opening at the benchmark's pace: a cycle in 90 frames), a moving camera, sensor
    noise, no occluder, 10 frames: each laptop gets its own track,
    kept with the same id (no identity switch) on every frame it is matched, its median rotation error below 10 deg;
    no track lies on pixels that are no object; the JSON line is plain."""
    from ancsh.data.scene_sequences import SceneSequenceConfig, render_scene_sequence
    from ancsh.learned.inference.predict import make_provider
    from ancsh.studies.stress_scenes import _errors, match_objects
    from ancsh.tracking.multi import MultiObjectTracker, MultiTrackerConfig

    cfg = SceneSequenceConfig("laptop", objects=2, length=10, occluder=False, period=90, seed=0)
    provider = make_provider("laptop")
    tracker = None
    ids, rots = {0: [], 1: []}, {0: [], 1: []}
    for f in render_scene_sequence(cfg, 2):
        if tracker is None:
            tracker = MultiObjectTracker(provider, f.intrinsics, "laptop", MultiTrackerConfig(detect_every=3))
        out = tracker.step(f.depth)
        line = json.loads(json.dumps(out.to_dict(), allow_nan=False))
        assert line["frame"] == f.index and len(line["tracks"]) == len(out.tracks)
        measured = [t for t in out.tracks if t.status in ("born", "tracked", "reinitialised")]
        matched, unmatched, _ = match_objects([t.mask for t in measured], [True] * len(measured),
                                              [o.visible for o in f.objects])
        assert unmatched == []
        for k, (i, _) in matched.items():
            ids[k].append(measured[i].id)
            rots[k].append(_errors(measured[i].model, f.objects[k].gt)[0])
    assert all(len(v) >= 5 for v in ids.values()), ids
    assert all(len(set(v)) == 1 for v in ids.values()) and ids[0][0] != ids[1][0]
    assert all(np.median(v) < 10.0 for v in rots.values()), rots


def test_multi_object_tracker_refuses_bad_input():
    from ancsh.data.render import Intrinsics
    from ancsh.tracking.multi import MultiObjectTracker, MultiTrackerConfig

    with pytest.raises(ValueError, match="detect_every"):
        MultiTrackerConfig(detect_every=0)
    with pytest.raises(ValueError, match="same_object_iou"):
        MultiTrackerConfig(same_object_iou=1.5)
    with pytest.raises(ValueError, match="provider"):
        MultiObjectTracker(object(), Intrinsics.kinect(64, 48), "laptop")
    from ancsh.learned.inference.predict import make_provider

    tracker = MultiObjectTracker(make_provider("laptop"), Intrinsics.kinect(64, 48), "laptop")
    with pytest.raises(ValueError, match="depth"):
        tracker.step(np.zeros((10, 10)))


def test_track_command_follows_every_object_and_writes_schema_2(tmp_path, capsys):
    """Scenario: ``ancsh track --category laptop`` on a folder of six frames of two laptops (one of them garbage):
    one ``ancsh.track/2`` line a frame, the garbage frame an ``error`` with no tracks, two track ids, a picture of each
    stepped frame and the states plot; options for every object are refused with ``--single``."""
    from ancsh.cli import main
    from ancsh.data.scene_sequences import SceneSequenceConfig, render_scene_sequence

    folder = tmp_path / "depth"
    folder.mkdir()
    for f in render_scene_sequence(SceneSequenceConfig("laptop", objects=2, length=6, occluder=False, period=90), 2):
        np.save(folder / f"frame_{f.index}.npy", f.depth)
        intrinsics = f.intrinsics
    (folder / "frame_3.npy").write_bytes(b"garbage")
    K = tmp_path / "K.json"
    K.write_text(json.dumps(intrinsics.to_json()))
    out = tmp_path / "tracks.jsonl"
    assert main(["track", "--depth", str(folder), "--intrinsics", str(K), "--category", "laptop", "--out", str(out),
                 "--quiet", "--png-dir", str(tmp_path / "png")]) == 0
    assert sorted(p.name for p in (tmp_path / "png").iterdir()) == [f"frame_{i}.png" for i in (0, 1, 2, 4, 5)] + ["states.png"]
    lines = [json.loads(line) for line in out.read_text().splitlines()]
    assert [r["frame"] for r in lines] == list(range(6)) and all(r["schema"] == "ancsh.track/2" for r in lines)
    assert "unreadable frame" in lines[3]["error"] and lines[3]["tracks"] == []
    assert len({t["id"] for r in lines for t in r["tracks"]}) == 2
    assert lines[0]["detected"] and all(len(t["joint_states"]) == 1 for r in lines for t in r["tracks"])
    assert main(["track", "--depth", str(folder), "--intrinsics", str(K), "--category", "laptop", "--single",
                 "--max-objects", "2", "--out", str(tmp_path / "other.jsonl")]) == 2
    assert "--max-objects / --detect-every / --png-dir" in capsys.readouterr().err
