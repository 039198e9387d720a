"""``ancsh bench latency``: the stage split of a profiled prediction, and the report's verdicts from its figures."""

from __future__ import annotations

import json

import numpy as np
import pytest

from ancsh.studies.latency import STAGES, stage_profile, write_latency_report
from ancsh.studies.report import Provenance


@pytest.fixture(scope="module")
def laptop_frame():
    from ancsh.data.generate import FrameGenerator, GenerationConfig

    gen = FrameGenerator(GenerationConfig(category="laptop", split="test", seed=0))
    frame = gen.frame(2)
    _, renderer = gen.instance(frame.instance_index)
    return renderer.render(frame.joint_states_abs, frame.T_cam_base, frame.intrinsics).depth, frame.intrinsics


def test_the_stages_of_a_prediction_add_up_to_its_time(laptop_frame):
    from ancsh.learned.inference.predict import predict_depth
    from ancsh.learned.inference.provider import LearnedProvider

    depth, intr = laptop_frame
    provider = LearnedProvider("laptop", seed=0, refine="auto")
    stages, total = stage_profile(lambda: predict_depth(depth, intr, "laptop", provider=provider, hypotheses=1))
    assert set(stages) == set(STAGES) | {"other"}
    assert all(v >= 0 for v in stages.values()) and sum(stages.values()) == pytest.approx(total, rel=1e-6)
    for stage in ("isolation", "network", "fit", "point sampling"):  # each ran, none holds the whole time
        assert 0 < stages[stage] < total


def _results(warm_ms: float, cold_s: float, rps: float) -> dict:
    warm = [{"frame": f, "category": "box", "pixels": 100, "hypotheses": h, "ms": warm_ms * (1 if h == 3 else 0.5),
             "ms_all": [warm_ms], "objects": 1, "timings_ms": {}} for f in ("a", "b") for h in (3, 1)]
    stages = [{"frame": "a", "profiled_ms": 10.0, "stages_ms": {**{s: 1.0 for s in STAGES}, "other": 3.0}}]
    return {"warm": warm, "stages": stages, "cold": {"frame": "a", "category": "box", "cli_s": 0.1, "torch_s": 0.5,
                                                      "predict_s": cold_s},
            "serve": {"frame": "a", "requests": 4, "seconds": 4 / rps, "rps": rps, "same_as_predict": True},
            "first_call": {"frame": "a", "load_ms": 1.0, "first_ms": 2.0, "first_network_ms": 1.0, "second_ms": 1.0,
                           "second_network_ms": 0.5},
            "workers": [{"workers": 1, "where": "this process", "frames": 6, "seconds": 1.0, "fps": 6.0},
                        {"workers": 1, "where": "spawned", "frames": 6, "seconds": 3.0, "fps": 2.0},
                        {"workers": 2, "where": "spawned", "frames": 6, "seconds": 2.0, "fps": 3.0}]}


@pytest.mark.parametrize("warm_ms, cold_s, rps, verdicts", [(80.0, 1.2, 9.0, ["yes", "yes", "yes"]),
                                                             (300.0, 3.0, 2.0, ["no", "no", "no"])])
def test_the_report_states_each_target_from_the_figures(tmp_path, warm_ms, cold_s, rps, verdicts):
    path = write_latency_report(_results(warm_ms, cold_s, rps), tmp_path / "latency.md", Provenance("ancsh bench latency"))
    text = path.read_text()
    rows = [line for line in text.splitlines() if line.startswith("| warm median") or line.startswith("| cold")
            or line.startswith("| `ancsh serve`")]
    assert [r.rstrip(" |").rsplit("| ", 1)[1] for r in rows] == verdicts
    assert "costs 2.00x the time" in text and "| **all** | 10 |" in text
    assert "| 2 | spawned | 6 | 2.0 | 3.00 |" in text and "2 spawned workers against 1: 1.50x" in text
    data = json.loads(path.with_suffix(".json").read_text())
    assert data["command"] == "ancsh bench latency" and np.isclose(data["serve"]["rps"], rps)
