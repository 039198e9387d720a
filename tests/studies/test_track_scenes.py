"""ancsh bench track-scenes: its per-object figures from known records."""

from __future__ import annotations

import numpy as np
import pytest

from ancsh.studies.track_scenes import summarise


def _row(track, rot=None, state=None, states=None, p_rot=None, p_state=None, p_states=None, moving=False):
    return {"object": 0, "visible": True, "moving": moving, "translucent": False, "track": track, "rot": rot,
            "state": state, "unit": "deg", "states": states, "p_rot": p_rot, "p_state": p_state, "p_states": p_states}


def test_summary_counts_switches_jumps_and_errors_on_shared_frames():
    """Track ids 0 0 1 - 1 on a still object, track 1 alive on frame 1 (while 0 held it): one switch, two tracks; errors only on frames where both have a fit;
    jumps only between consecutive frames of one track (degrees), predict's between consecutive fits."""
    rows = [_row(0, 2.0, 1.0, [0.0], 4.0, 2.0, [0.0]),
            _row(0, 2.0, 1.0, [np.deg2rad(1.0)], None, None, None),
            _row(1, 4.0, 3.0, [np.deg2rad(10.0)], 4.0, 2.0, [np.deg2rad(5.0)]),
            _row(None, None, None, None, 6.0, 1.0, [np.deg2rad(6.0)]),
            _row(1, 3.0, 2.0, [np.deg2rad(11.0)], None, None, None)]
    frames = [{"frame": i, "objects": [r], "false_track": i % 2, "false_predict": 0, "live": live}
              for i, (r, live) in enumerate(zip(rows, [[0], [0, 1], [1], [1], [1]]))]
    s = summarise({"category": "laptop", "sequence": "pair", "frames": frames, "track_s": 0.5,
                   "stage_ms": {"measure": 250.0}})
    o = s["objects"][0]
    assert o["switches"] == 1 and o["fragments"] == 0 and o["tracks"] == 2 and o["found"] == 4 and o["predict_found"] == 3
    assert o["both"] == 2 and o["rot"] == pytest.approx(3.0) and o["p_rot"] == pytest.approx(4.0)
    assert o["state"] == pytest.approx(2.0) and o["p_state"] == pytest.approx(2.0)
    assert o["jump_p95"] == pytest.approx(1.0)  # 0 -> 1 deg; 1 -> 10 changes track, 10 -> 11 skips a frame
    assert o["p_jump_p95"] == pytest.approx(np.percentile([1.0], 95))  # predict: 5 -> 6 deg (frames 2, 3)
    assert s["false_track"] == 2 and s["fps"] == pytest.approx(10.0) and s["stage_share"]["measure"] == pytest.approx(0.5)


def test_a_moving_object_has_no_jump_figure():
    rows = [_row(0, 1.0, 1.0, [0.0], moving=True), _row(0, 1.0, 1.0, [0.5], moving=True)]
    frames = [{"frame": i, "objects": [r], "false_track": 0, "false_predict": 0} for i, r in enumerate(rows)]
    o = summarise({"category": "laptop", "sequence": "pair", "frames": frames, "track_s": 0.1, "stage_ms": {}})["objects"][0]
    assert o["moving"] and o["jump_p95"] is None


def test_a_new_track_after_the_old_one_ended_is_a_fragment_not_a_switch():
    rows = [_row(0), _row(None), _row(2)]
    frames = [{"frame": i, "objects": [r], "false_track": 0, "false_predict": 0, "live": live}
              for i, (r, live) in enumerate(zip(rows, [[0], [], [2]]))]
    o = summarise({"category": "laptop", "sequence": "pair", "frames": frames, "track_s": 0.1, "stage_ms": {}})["objects"][0]
    assert o["switches"] == 0 and o["fragments"] == 1 and o["tracks"] == 2


def test_a_track_matched_to_two_objects_is_counted():
    a, b = _row(5), dict(_row(5), object=1)
    frames = [{"frame": 0, "objects": [a, dict(_row(None), object=1)], "false_track": 0, "false_predict": 0, "live": [5]},
              {"frame": 1, "objects": [_row(None), b], "false_track": 0, "false_predict": 0, "live": [5]}]
    s = summarise({"category": "laptop", "sequence": "pair", "frames": frames, "track_s": 0.1, "stage_ms": {}})
    assert s["wandering"] == 1
