"""Training with ``TrainConfig.compile``: the trainer, the cost benchmark and the configuration.

Scenario: a tiny network on random clouds. A trainer with ``compile=True`` steps through a compiled
wrapper of its network, writes checkpoints that load into the uncompiled network (no ``_orig_mod.``
keys) and resumes with compilation on or off; ``bench learned-cost`` times the compilation apart. These
tests use dynamo's ``eager`` backend in place of inductor (the same wrapper, no C++ compilation); that
the inductor-compiled step computes the reference step's function is checked in float64 by
``tests/learned/test_learned_step_cost.py`` (slow, skipped without a C++ compiler).
"""

import numpy as np
import pytest
import torch

from ancsh.learned.training.compiled import compile_network, cxx_compiler
from ancsh.learned.network.config import TrainConfig
from ancsh.learned.network.models import build_network
from ancsh.learned.training.train import Trainer


def test_trainer_with_compile_trains_checkpoints_and_resumes(tmp_path, tiny_arrays, tiny_config, monkeypatch):
    """The trainer's handling of a compiled module (a ``torch.compile`` wrapper); dynamo with its ``eager``
    backend stands in for inductor here (the same wrapper, no C++ compilation: fast, and on any machine)."""
    from dataclasses import replace

    import ancsh.learned.training.compiled as compiled_module

    wrapped = []

    def compile_eager(model):
        wrapped.append(torch.compile(model, dynamic=False, backend="eager"))
        return wrapped[-1]

    monkeypatch.setattr(compiled_module, "compile_network", compile_eager)
    cfg = replace(tiny_config, compile=True)
    plain = Trainer(tiny_config, tiny_arrays, None, None, progress=False)
    trainer = Trainer(cfg, tiny_arrays, None, tmp_path / "run", progress=False)
    assert wrapped and trainer.step_model is wrapped[-1] and trainer.step_model is not trainer.model
    first, first_plain = trainer.train_step(), plain.train_step()
    for k in first:  # the same loss on the same initial weights, to float32 rounding: the traced graph sums in
        # another order (measured up to 1.0e-5 relative on the joint loss on an AMD EPYC, 2026-12-02)
        assert abs(first[k] - first_plain[k]) <= 1e-4 * max(1.0, abs(first_plain[k])), k
    trainer.fit(max_steps=3)
    ck = torch.load(tmp_path / "run" / "last.pt", weights_only=True)
    assert not any(k.startswith("_orig_mod.") for k in ck["model"])
    fresh = build_network("ancsh", tiny_arrays.num_parts, tiny_arrays.num_joints, **cfg.network_kwargs())
    fresh.load_state_dict(ck["model"])  # the uncompiled network loads it (strict)
    assert TrainConfig.from_json(tmp_path / "run" / "config.json").compile is True
    resumed = Trainer(cfg, tiny_arrays, None, tmp_path / "run", progress=False)
    resumed.load_checkpoint(tmp_path / "run" / "last.pt")
    losses = resumed.fit(max_steps=5)
    assert resumed.step == 5 and len(losses) == 2 and all(np.isfinite(s["total"]) for s in losses)
    uncompiled = Trainer(tiny_config, tiny_arrays, None, tmp_path / "run", progress=False)  # resume with it off
    uncompiled.load_checkpoint(tmp_path / "run" / "last.pt")
    assert uncompiled.step == 5 and uncompiled.step_model is uncompiled.model


def test_cost_benchmark_times_the_compilation_apart(tmp_path, monkeypatch):
    """``bench learned-cost`` with the compiled variant (dynamo's ``eager`` backend standing in for inductor)."""
    import ancsh.learned.training.compiled as compiled_module
    from ancsh.studies.learned_cost import training_cost, write_cost_report

    monkeypatch.setattr(compiled_module, "compile_network", lambda m: torch.compile(m, dynamic=False, backend="eager"))
    result = training_cost(("today", "new", "new_compiled"), width=0.125, num_points=256, repeats=2)
    rows = {r["name"]: r for r in result["rows"]}
    assert rows["new_compiled"]["compile_cpu_s"] > 0 and "compile_cpu_s" not in rows["new"]
    assert abs(rows["new_compiled"]["first_loss"] - rows["today"]["first_loss"]) < 1e-4 * abs(rows["today"]["first_loss"])
    text = write_cost_report(result, tmp_path / "cost.md", command="ancsh bench learned-cost").read_text()
    assert "Compilation (new step compiled: torch.compile" in text and "Compiled against uncompiled new step" in text
    assert "Best variant that computes the same function as today's step" in text


def test_compile_config_is_checked_and_a_missing_compiler_is_a_clear_error(monkeypatch):
    with pytest.raises(ValueError, match="compile"):
        TrainConfig(compile="yes")
    assert TrainConfig.from_dict({}).compile is False  # configs of earlier runs (no such key) keep working
    monkeypatch.setenv("CXX", "no-such-compiler-ancsh")
    assert cxx_compiler() is None
    with pytest.raises(RuntimeError, match="C\\+\\+ compiler"):
        compile_network(build_network("ancsh", 2, 1, width=0.125, npoints=(32, 8), nsamples=(8, 8)))
