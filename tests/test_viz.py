"""Interactive plotly views of a prediction and of a track (skipped without plotly, an optional extra)."""

import numpy as np
import pytest

pytest.importorskip("plotly")

from ancsh.viz import prediction_figure, track_figure  # noqa: E402


@pytest.fixture(scope="module")
def prediction():
    from ancsh.data.generate import FrameGenerator, GenerationConfig
    from ancsh.learned.inference.predict import predict_depth

    gen = FrameGenerator(GenerationConfig(category="laptop", split="test", seed=0))
    fr = gen.frame(2)  # an open laptop (frame 1, closed to 10 deg, is fitted 52 deg off and rejected)
    _, renderer = gen.instance(fr.instance_index)
    depth = renderer.render(fr.joint_states_abs, fr.T_cam_base, fr.intrinsics).depth
    return predict_depth(depth, fr.intrinsics, "laptop", mask=depth > 0)


def test_prediction_figure_has_points_boxes_axes_and_model_meshes(prediction):
    assert prediction.result.ok
    fig = prediction_figure(prediction)
    names = [t.name for t in fig.data]
    for part in prediction.part_names:
        assert f"{part} points" in names and f"{part} box" in names and f"{part} model" in names
    assert f"{prediction.joint_names[0]} axis" in names
    points = sum(len(t.x) for t in fig.data if t.name.endswith(" points"))
    assert points == len(prediction.points_cam)
    assert fig.layout.scene.aspectmode == "data"
    assert len(prediction_figure(prediction, mesh=False).data) == len(fig.data) - len(prediction.part_names)


def test_track_figure_slider_shows_one_frame_at_a_time(prediction):
    from ancsh.tracking.records import TrackedFrame, TrackStatus

    tracked = TrackedFrame(0, TrackStatus.TRACKED, "", prediction.result, prediction.result.joint_states, "network")
    lost = TrackedFrame(1, TrackStatus.LOST, "", None, np.full(1, np.nan), "none")
    fig = track_figure([(prediction.points_cam, prediction.part_labels, tracked), (prediction.points_cam, None, lost)],
                       prediction.part_names, prediction.joint_names)
    steps = fig.layout.sliders[0].steps
    assert len(steps) == 2 and "tracked" in steps[0].label and "lost" in steps[1].label
    for step in steps:
        assert any(step.args[0]["visible"])
    first = sum(steps[0].args[0]["visible"])
    assert [t.visible for t in fig.data][:first] == [True] * first and not any(t.visible for t in fig.data[first:])
    with pytest.raises(ValueError, match="frames"):
        track_figure([], prediction.part_names, prediction.joint_names)
