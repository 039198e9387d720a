"""ancsh bench scaling: what it measures and the report it writes."""

import pytest

from ancsh.cli import main
from ancsh.studies.scaling import Run, ScalingResult, scaling_report


def _result():
    runs = (
        Run("generate", "in-process", 1, 10, wall_s=3.0, first_s=1.0, first_frames=2, cpu_s=1.6),
        Run("generate", "local", 1, 10, wall_s=6.0, first_s=2.0, first_frames=2),
        Run("generate", "local", 2, 10, wall_s=5.0, first_s=3.0, first_frames=2),
        Run("generate", "ray", 1, 10, wall_s=9.0, first_s=5.0, first_frames=2),
        Run("generate", "ray", 2, 10, wall_s=7.0, first_s=5.0, first_frames=2),
        Run("evaluate", "in-process", 1, 4, wall_s=5.0, first_s=2.0, first_frames=1, cpu_s=1.5),
        Run("evaluate", "local", 1, 4, wall_s=10.0, first_s=4.0, first_frames=1),
        Run("evaluate", "local", 2, 4, wall_s=8.0, first_s=5.0, first_frames=1),
        Run("evaluate", "ray", 1, 4, wall_s=12.0, first_s=6.0, first_frames=1),
        Run("evaluate", "ray", 2, 4, wall_s=10.0, first_s=7.0, first_frames=1),
    )
    settings = dict(gen_frames=10, chunk=2, eval_frames=4, rounds=1, workers=[1, 2], executors=["local", "ray"],
                    category="laptop")
    return ScalingResult(runs, 9.5, (3.0, 2.0, 1.0), (3.5, 2.1, 1.0), 2, settings)


def test_report_rows_are_medians_and_ratios_of_the_runs():
    r = _result()
    assert r.runs[1].steady_frames_per_s == pytest.approx(8 / 4)
    assert r.cpu_per_frame("generate") == pytest.approx(1.6 / 8) and r.cpu_per_frame("evaluate") == pytest.approx(0.5)
    text = scaling_report(r, command="ancsh bench scaling --rounds 1")
    assert "by `ancsh bench scaling --rounds 1`" in text and "3.0 / 2.0 / 1.0 before" in text
    assert "| generate | in-process | 1 | 3.0 | 1.0 | 3.33 | 4.00 | 2.00x | - |" in text
    assert "| generate | local | 2 | 5.0 | 3.0 | 2.00 | 4.00 | 2.00x | - |" in text  # 8 frames in 2 s after the first
    assert "| generate | ray | 2 | 7.0 | 5.0 | 1.43 | 4.00 | 2.00x | 1.40 |" in text  # 7 s / 5 s of local x2
    assert "generation 0.200 CPU-s, evaluation 0.500 CPU-s" in text
    # 1e6 frames x 0.5 CPU-s in 8 h = 17.4 -> 18 cores
    assert "| 1,000,000 | 56 | 7 | 3 | 139 | 18 | 6 |" in text
    assert "Starting the local Ray itself took 9.5 s" in text


@pytest.mark.slow
def test_cli_measures_and_writes_the_report(tmp_path, capsys):
    out = tmp_path / "scaling.md"
    args = ["bench", "scaling", "--gen-frames", "2", "--chunk", "1", "--eval-frames", "2", "--rounds", "1",
            "--workers", "1", "--executors", "local", "--out", str(out)]
    assert main(args) == 0
    text = out.read_text()
    assert f"`ancsh bench scaling --gen-frames 2 --chunk 1 --eval-frames 2 --rounds 1 --workers 1 --executors local --out {out}`" in text
    assert "| generate | local | 1 |" in text and "| evaluate | in-process | 1 |" in text
    assert main(["bench", "scaling", "--executors", "dask"]) == 2
    assert "--executors: expected 'local' and optionally 'ray'" in capsys.readouterr().err
