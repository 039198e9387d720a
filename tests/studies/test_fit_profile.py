"""``ancsh bench fit-profile`` on one frame: runs in-process and writes its page with every stage."""

import json

import pytest

from ancsh.studies.fit_profile import ProfileConfig


def test_profile_command_writes_the_stages_and_the_ratio(tmp_path, capsys):
    from ancsh.cli import main

    out = tmp_path / "fit_profile.md"
    assert main(["bench", "fit-profile", "--frames", "1", "--categories", "laptop", "--repeats", "2",
                 "--out", str(out)]) == 0
    text = out.read_text()
    assert "`ancsh bench fit-profile --frames 1 --categories laptop --repeats 2 --out " in text
    assert "| laptop | exact_reduced/ipopt | 100% |" in text and "| laptop | exact_reduced/lm | 100% |" in text
    assert "total for 1000x" in text and "ipopt.internal" in text and "lm.evaluate" in text
    assert "`ancsh bench fit --frames 1 --levels realistic --categories laptop`" in text
    assert "Methods: exact_reduced/lm, exact_reduced/ipopt (default" in text
    payload = json.loads(out.with_suffix(".json").read_text())
    rows = {r["method"]: r for r in payload["rows"]}
    for m, r in rows.items():
        assert {"ransac", "solve", "covariance", "result"} <= set(r["stages_ms"])
        assert 0 < sum(r["stages_ms"].values()) < 10 * r["total_ms"]  # medians of the stages: of the order of the total
        assert r["ratio"] == pytest.approx(r["official_ms"] / r["total_ms"])
    assert rows["exact_reduced/ipopt"]["solver_ms"]["ipopt.iterations"] >= 1
    assert rows["exact_reduced/lm"]["solver_ms"]["lm.iterations"] >= 1
    assert "smallest official / total" in capsys.readouterr().out


def test_profile_config_names_bad_arguments():
    with pytest.raises(ValueError, match="methods: unknown 'exact_reduced/nope'"):
        ProfileConfig(methods=("exact_reduced/nope",))
    with pytest.raises(ValueError, match="level"):
        ProfileConfig(level="extreme")
    with pytest.raises(ValueError, match="repeats"):
        ProfileConfig(repeats=0)
