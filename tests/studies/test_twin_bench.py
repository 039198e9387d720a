"""ancsh bench twin: the exported model of an exact (oracle) fit explains the depth it was fitted to."""

import json

import numpy as np
import pytest

from ancsh.cli import main
from ancsh.learned.inference.predict import URDF_ALIGN, URDF_CANDIDATES
from ancsh.studies.twin import TARGET_M, measure_twin, summarize


def test_an_oracle_fit_model_explains_its_depth_within_the_target():
    results = measure_twin(["laptop"], frames=2, progress=False)
    rows = {r["provider"]: r for r in summarize(results)}
    assert {r["selection"] for r in summarize(results)} == {"instance", "nearest"}
    assert rows["oracle"]["failed"] == 0 and rows["oracle"]["median_residual_m"] < TARGET_M
    assert rows["oracle"]["explained"] > 0.9 and rows["oracle"]["see_through"] < 0.05
    assert rows["learned"]["frames"] == 2 and np.isfinite(rows["learned"]["median_residual_m"])
    assert rows["learned"]["refined"] is None and 0.0 <= rows["learned+template"]["refined"] <= 1.0
    assert rows["learned+network"]["frames"] == 2 and 0.0 <= rows["learned+network"]["refined"] <= 1.0  # laptop ships one


def test_the_network_refinement_runs_only_where_a_refiner_is_shipped(monkeypatch, tmp_path):
    """A category without a shipped refinement network (its refiner file missing here) has no learned+network rows."""
    from ancsh.learned.network import weights

    shipped = weights.weights_path
    monkeypatch.setattr(weights, "weights_path", lambda category, kind="ancsh": tmp_path / "none.pt" if kind == "refine"
                        else shipped(category, kind))
    results = measure_twin(["safe"], frames=1, progress=False, candidates=1)
    assert {r["provider"] for r in results["records"]} == {"instance", "learned", "learned+template", "oracle"}
    assert "learned+network" not in {r["provider"] for r in summarize(results)}


def test_cli_writes_the_report_and_checks_categories(tmp_path, capsys):
    out = tmp_path / "twin.md"
    assert main(["bench", "twin", "--categories", "laptop", "--frames", "1", "--out", str(out), "--quiet"]) == 0
    text = out.read_text()
    assert "| laptop | oracle | nearest | 1 | 0 |" in text and f"| laptop | oracle | best of {URDF_CANDIDATES} | 1 | 0 |" in text
    assert f"| laptop | oracle | best of {URDF_CANDIDATES}, {URDF_ALIGN} aligned | 1 | 0 |" in text
    data = json.loads(out.with_suffix(".json").read_text())
    assert data["command"].startswith("ancsh bench twin --categories laptop --frames 1") and len(data["records"]) == 13
    assert "--candidates" not in data["command"] and "--align" not in data["command"]
    assert main(["bench", "twin", "--categories", "laptop", "--candidates", "1", "--align", "2", "--out",
                 str(tmp_path / "y.md")]) == 2
    assert "--align: aligns the best of several templates" in capsys.readouterr().err
    assert main(["bench", "twin", "--categories", "nothing", "--out", str(tmp_path / "x.md")]) == 2
    assert "--categories: no shipped weights for ['nothing']" in capsys.readouterr().err


def test_the_exported_twin_does_not_depend_on_the_fits_box_extents(tmp_path):
    """``--box-extents unit_diagonal`` sets the fits' boxes, but the exported model is shaped from unit-diagonal boxes
    either way (``EXPORT_BOX_EXTENTS``): the plain and the network-refined learned fits' twins, the oracle's and the
    floor are the same as with ``max`` boxes (only the template refinement, which reshapes its template to the fit's
    own boxes, may differ)."""
    out = tmp_path / "twin.md"
    assert main(["bench", "twin", "--categories", "laptop", "--frames", "1", "--box-extents", "unit_diagonal",
                 "--out", str(out), "--quiet"]) == 0
    data = json.loads(out.with_suffix(".json").read_text())
    assert "--box-extents unit_diagonal" in data["command"] and "`unit_diagonal`" in out.read_text()
    plain = measure_twin(["laptop"], frames=1, progress=False)
    scaled = {r["provider"]: r for r in data["records"] if r["selection"] in ("nearest", "instance")}
    assert {"learned", "learned+network", "oracle", "instance"} <= set(scaled)
    for r in plain["records"]:
        if r["selection"] in ("nearest", "instance") and r["provider"] != "learned+template":
            assert r["median_abs_residual_m"] == pytest.approx(scaled[r["provider"]]["median_abs_residual_m"],
                                                               abs=1e-12), r["provider"]


def test_the_best_of_k_templates_is_chosen_on_the_same_fit_and_never_explains_the_depth_worse():
    """``candidates=K``: the same fits, the template chosen by render-and-compare; per frame its residual is at most the
    nearest template's (the nearest is among the K), and the aligned choice's at most that; the choices are recorded
    side by side."""
    results = measure_twin(["laptop"], frames=2, progress=False, candidates=3, align=1)
    by_key = {}
    for r in results["records"]:
        by_key.setdefault((r["frame"], r["provider"]), {})[r["selection"]] = r
    assert len(by_key) == 10
    assert all(set(v) == ({"instance"} if p == "instance" else {"nearest", "best of 3", "best of 3, 1 aligned"})
               for (_, p), v in by_key.items())
    for (_, provider), v in by_key.items():
        if provider == "instance":
            continue
        assert v["best of 3"]["median_abs_residual_m"] <= v["nearest"]["median_abs_residual_m"] + 1e-12
        aligned = v["best of 3, 1 aligned"]
        assert aligned["median_abs_residual_m"] <= v["best of 3"]["median_abs_residual_m"] + 1e-12
        assert aligned["aligned"] == (aligned["median_abs_residual_m"] < v["best of 3"]["median_abs_residual_m"])
    assert results["settings"]["candidates"] == 3 and results["settings"]["align"] == 1
    for frame in (0, 1):  # a refinement starts from the learned fit: where it is not kept, nothing changes
        plain = by_key[(frame, "learned")]["nearest"]
        for provider in ("learned+template", "learned+network"):
            refined = by_key[(frame, provider)]["nearest"]
            same = plain["median_abs_residual_m"] == refined["median_abs_residual_m"]
            assert same == (not refined["refined"]), (frame, provider)


def test_the_instance_floor_is_the_sensor_noise_alone():
    """The ``instance`` row renders the frame's own model at its true pose and states: against the noise-free depth it
    explains every pixel with zero residual; against the noisy depth, what is left is the noise."""
    from dataclasses import replace

    from ancsh.data.generate import FrameGenerator, GenerationConfig
    from ancsh.studies.twin import instance_floor

    gen = FrameGenerator(GenerationConfig(category="laptop", split="test", seed=0))
    fr = gen.frame(0, keep_depth=True)
    _, renderer = gen.instance(fr.instance_index)
    clean = renderer.render(fr.joint_states_abs, fr.T_cam_base, fr.intrinsics).depth
    exact = instance_floor(gen, replace(fr, depth=clean))
    assert exact["median_abs_residual_m"] == 0.0 and exact["explained"] == 1.0 and exact["see_through"] == 0.0
    noisy = instance_floor(gen, fr)
    assert 0.0 < noisy["median_abs_residual_m"] == pytest.approx(np.median(np.abs(fr.depth - clean)[(fr.depth > 0) & (clean > 0)]))
