"""The cheaper training step computes the same thing as the reference step.

Scenario: a network of the shipped layout (smaller) on random clouds. The per-frame neighbourhood
cache equals freshly computed neighbourhoods (bit-exact indices); the channel-last layers with
cached neighbourhoods give the reference step's loss and gradients (float64, to rounding); the
numpy farthest-point sampling equals the torch reference; so does the compiled network's step
(``torch.compile``, slow: it compiles C++ kernels; skipped without a C++ compiler).
"""

import copy

import numpy as np
import pytest
import torch

from ancsh.learned.training.compiled import compile_network, cxx_compiler
from ancsh.learned.training.losses import ancsh_loss
from ancsh.learned.network.models import build_network
from ancsh.learned.network.pointnet2 import farthest_point_sample, farthest_point_sample_reference
from ancsh.learned.training.train import Trainer, neighbourhood_cache


def _net(kind="ancsh", **kw):
    torch.manual_seed(0)
    return build_network(kind, 2, 1, width=0.125, npoints=(32, 8), nsamples=(8, 8), **kw)


def test_numpy_fps_equals_the_torch_reference():
    g = torch.Generator().manual_seed(0)
    for dtype in (torch.float32, torch.float64):
        xyz = torch.rand(5, 200, 3, generator=g, dtype=dtype)
        xyz[1, 50:60] = xyz[1, 40]  # repeated points: ties go to the lowest index in both
        assert torch.equal(farthest_point_sample(xyz, 64), farthest_point_sample_reference(xyz, 64))
    with pytest.raises(ValueError, match="npoint"):
        farthest_point_sample_reference(xyz, 201)


def test_neighbourhood_cache_equals_fresh_computation(tmp_path, tiny_arrays):
    net = _net()
    cache = neighbourhood_cache(net, tiny_arrays.points, batch_size=3, path=tmp_path / "nb.npz")
    fresh = net.neighbourhoods(torch.from_numpy(tiny_arrays.points))
    for name, value in fresh.numpy().items():
        assert cache[name].dtype == value.dtype and cache[name].shape[0] == len(tiny_arrays)
        if np.issubdtype(value.dtype, np.integer):
            np.testing.assert_array_equal(cache[name], value, err_msg=name)  # bit-exact indices
        else:
            np.testing.assert_allclose(cache[name], value, rtol=1e-6, atol=0, err_msg=name)
    again = neighbourhood_cache(net, tiny_arrays.points, path=tmp_path / "nb.npz")  # read back from the file
    for name in cache:
        np.testing.assert_array_equal(again[name], cache[name])
    other = tiny_arrays.points.copy()
    other[0, 0, 0] += 0.01  # other points: the stale file is not used
    moved = neighbourhood_cache(net, other, path=tmp_path / "nb.npz")
    np.testing.assert_array_equal(moved["groups1"], net.neighbourhoods(torch.from_numpy(other)).numpy()["groups1"])


def _float64_case(arrays, kind="ancsh"):
    """A float64 network, batch and neighbourhoods of ``arrays``, and ``step(model, call, nb) -> (loss, grads)``
    (``call`` evaluates ``model``: itself or a compiled wrapper)."""
    net = _net(kind).double()
    points, targets = arrays.batch(np.arange(len(arrays)))
    points = points.double()
    targets = type(targets)(**{k: v.double() if v.is_floating_point() else v for k, v in vars(targets).items()})
    loss_fn = ancsh_loss
    if kind == "direct_voting":
        from ancsh.learned.training.losses import direct_voting_loss as loss_fn

    def step(model, call, neighbourhoods):
        model.zero_grad()
        total, _ = loss_fn(call(points, neighbourhoods), targets)
        total.backward()
        return total, {n: p.grad.clone() for n, p in model.named_parameters()}

    return net, points, net.neighbourhoods(points), step


def _assert_same_step(net, ref_net, step, ref_step):
    """Loss, parameter gradients and batch-norm running statistics agree to float64 rounding."""
    (loss, grad), (ref_loss, ref_grad) = step, ref_step
    torch.testing.assert_close(loss, ref_loss, rtol=1e-10, atol=1e-12)
    for name in ref_grad:
        torch.testing.assert_close(grad[name], ref_grad[name], rtol=1e-8, atol=1e-10, msg=name)
    for (name, b), (_, b_ref) in zip(net.named_buffers(), ref_net.named_buffers()):  # batch-norm running stats
        torch.testing.assert_close(b, b_ref, rtol=1e-10, atol=1e-12, msg=name)


@pytest.mark.parametrize("kind", ["ancsh", "direct_voting"])
def test_channel_last_cached_step_matches_the_reference_step(tiny_arrays, kind):
    net, points, nb, step = _float64_case(tiny_arrays, kind)
    ref_net = copy.deepcopy(net)
    ref_net.backbone.channels_last = False
    ref = step(ref_net, ref_net, None)
    _assert_same_step(net, ref_net, step(net, net, nb), ref)  # (the float32 cache would round the float64 weights)
    with pytest.raises(ValueError, match="neighbourhoods"):
        ref_net(points, nb)


@pytest.mark.parametrize("backend", [
    "eager",  # dynamo traces the network (the compiled path of the layers) without generating code: fast, any machine
    pytest.param("inductor", marks=[
        pytest.mark.slow,  # C++ compilation: tens of seconds
        pytest.mark.filterwarnings("ignore:`torch.jit.script_method` is deprecated:DeprecationWarning"),  # inside inductor
        pytest.mark.skipif(cxx_compiler() is None, reason="torch.compile on a CPU needs a C++ compiler ($CXX or g++ on "
                           "the PATH); none found")]),
])
def test_compiled_step_matches_the_reference_step(tiny_arrays, monkeypatch, backend):
    """The compiled network (``TrainConfig.compile``) pools the set-abstraction layers before their last batch norm
    and ReLU (:meth:`SharedMLP.forward_last_max`) and inductor fuses kernels that only reorder sums: the float64 step
    agrees to rounding as the channel-last one does (a changed function would differ at the 1e-2 level)."""
    import ancsh.learned.network.pointnet2 as pointnet2

    pooled_first = []
    affine = pointnet2._batch_norm_affine
    monkeypatch.setattr(pointnet2, "_batch_norm_affine", lambda bn, h: pooled_first.append(bn) or affine(bn, h))
    net, _, nb, step = _float64_case(tiny_arrays)
    ref_net = copy.deepcopy(net)
    ref_net.backbone.channels_last = False
    compiled = compile_network(net) if backend == "inductor" else torch.compile(net, dynamic=False, backend="eager")
    for _ in range(2):  # running stats move on in both (the spy's list makes dynamo trace the second call again)
        ref = step(ref_net, ref_net, None)
        _assert_same_step(net, ref_net, step(net, compiled, nb), ref)
    last_bns = {id(sa.mlp[-2]) for sa in (net.backbone.sa1, net.backbone.sa2, net.backbone.sa3)}
    assert {id(bn) for bn in pooled_first} == last_bns  # the pooled-first path, traced for each set abstraction
    assert any(k.startswith("_orig_mod.") for k in compiled.state_dict())  # the wrapper's keys are prefixed ...
    assert set(net.state_dict()) == set(ref_net.state_dict())  # ... the network's own, which checkpoints hold, are not


@pytest.mark.parametrize("momentum, track", [(0.1, True), (None, True), (0.1, False)])
def test_batch_norm_affine_has_the_semantics_of_batch_norm(momentum, track):
    from ancsh.learned.network.pointnet2 import _batch_norm_affine

    g = torch.Generator().manual_seed(1)
    h = torch.randn(50, 6, generator=g, dtype=torch.float64) * 3 + 1
    bn = torch.nn.BatchNorm1d(6, momentum=momentum, track_running_stats=track).double()
    with torch.no_grad():
        bn.weight.copy_(torch.randn(6, generator=g))  # negative scales too
        bn.bias.copy_(torch.randn(6, generator=g))
    ref = copy.deepcopy(bn)
    for training in (True, True, False):
        bn.train(training)
        ref.train(training)
        scale, shift = _batch_norm_affine(bn, h)
        torch.testing.assert_close(h * scale + shift, ref(h), rtol=1e-12, atol=1e-12)
        for (name, b), b_ref in zip(bn.named_buffers(), ref.buffers()):
            torch.testing.assert_close(b, b_ref, rtol=1e-12, atol=0, msg=name)


def test_eval_mode_outputs_agree_between_layouts(tiny_arrays):
    net = _net().eval()
    ref = copy.deepcopy(net)
    ref.backbone.channels_last = False
    x = torch.from_numpy(tiny_arrays.points)
    with torch.no_grad():
        out, out_ref = net(x), ref(x)
    for k in out:
        torch.testing.assert_close(out[k], out_ref[k], rtol=1e-4, atol=1e-5, msg=k)


def test_trainer_caches_neighbourhoods_once_per_frame(tmp_path, tiny_arrays, tiny_config):
    trainer = Trainer(tiny_config, tiny_arrays, None, tmp_path / "run", progress=False)
    assert (tmp_path / "run" / "neighbourhoods.npz").is_file()
    fresh = trainer.model.neighbourhoods(torch.from_numpy(tiny_arrays.points)).numpy()
    np.testing.assert_array_equal(trainer.neighbourhoods["groups1"], fresh["groups1"])
    trainer.fit(max_steps=2)
    assert trainer.step == 2


def test_cost_benchmark_measures_variants_side_by_side_and_writes_its_command(tmp_path):
    from ancsh.studies.learned_cost import training_cost, write_cost_report

    result = training_cost(("today", "new"), width=0.125, num_points=256, repeats=2)
    rows = {r["name"]: r for r in result["rows"]}
    assert rows["today"]["speedup_cpu"] == 1.0 and rows["new"]["frames_per_cpu_s"] > 0
    assert abs(rows["today"]["first_loss"] - rows["new"]["first_loss"]) < 1e-3 * abs(rows["today"]["first_loss"])
    assert set(result["forward_ms"]) == {"reference", "channels_last"}
    path = write_cost_report(result, tmp_path / "cost.md", command="ancsh bench learned-cost --repeats 2")
    text = path.read_text()
    assert "Command: `ancsh bench learned-cost --repeats 2`" in text and "today's step" in text
    assert path.with_suffix(".json").is_file()
    with pytest.raises(ValueError, match="repeats"):
        training_cost(("new",), repeats=1)
