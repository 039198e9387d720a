"""Benchmarks of the network size against cost and accuracy (prints numbers, asserts nothing).

``python -m ancsh.cli.bench.learned timing`` -- training-step and single-frame forward times for
several widths / sampling settings (batch 16, 1024 points by default).

``python -m ancsh.cli.bench.learned accuracy --data DIR --steps S`` -- short equal-step training
runs at several widths on the same data, validation metrics on held-out instances.

``python -m ancsh.cli.bench.learned pipeline --data DIR --weights laptop`` -- the learned provider
followed by each fitting formulation on test frames: per-part rotation/translation errors,
joint-state error, and the time of the network and of each fit.

Results go to stdout as a markdown table (and ``--json`` to a file).

``ancsh bench learned-cost`` -- training frames per CPU-second of today's step (reference 1x1
convolutions, sampling and grouping at every step) beside the new one (channel-last layers,
per-frame cached neighbourhoods) and variants (batch, threads, bf16, torch.compile), measured in one process
with interleaved repetitions, plus the single-frame forward time; a Markdown table that names
its command, written to a fresh folder (or ``--out``).
"""

from __future__ import annotations

import copy
import json
import os
import platform
import time
from dataclasses import asdict, dataclass

import numpy as np

__all__ = ["SETTINGS", "STEP_VARIANTS", "StepVariant", "timing", "accuracy", "pipeline", "training_cost"]

SETTINGS = {
    # name: (width, npoints, nsamples, backbones)
    "w0.125": (0.125, (256, 64), (32, 32), 1),
    "w0.25": (0.25, (256, 64), (32, 32), 1),
    "w0.5": (0.5, (256, 64), (32, 32), 1),
    "w0.5-2bb": (0.5, (256, 64), (32, 32), 2),
    "w1.0": (1.0, (256, 64), (32, 32), 1),
    "w1.0-ref": (1.0, (512, 128), (32, 64), 1),
}


def _config(name: str, **kw):
    from ...learned.network.config import TrainConfig

    width, npoints, nsamples, backbones = SETTINGS[name]
    return TrainConfig(width=width, npoints=npoints, nsamples=nsamples, backbones=backbones, **kw)


def timing(names, *, batch: int = 16, num_points: int = 1024, threads: int = 1, repeats: int = 4) -> list[dict]:
    """Median training-step time (batch ``batch``) and single-frame forward time per setting.

    Wall and process CPU times are both reported: on a shared machine the CPU time of a
    one-thread run is the cost the network itself needs.
    """
    import torch

    from ...learned.training.losses import Targets, ancsh_loss
    from ...learned.network.models import build_network

    torch.set_num_threads(threads)
    g = torch.Generator().manual_seed(0)
    x = torch.randn(batch, num_points, 3, generator=g) * 0.1 + torch.tensor([0.0, 0.0, 1.5])
    t = Targets(
        torch.randint(0, 2, (batch, num_points), generator=g), torch.rand(batch, num_points, 3, generator=g),
        torch.rand(batch, num_points, generator=g) + 0.5, torch.rand(batch, num_points, 3, generator=g),
        torch.randint(0, 2, (batch, num_points), generator=g), torch.rand(batch, num_points, 7, generator=g),
        torch.ones(batch, num_points, 7), torch.rand(batch, num_points, 7, generator=g),
    )
    rows = []
    for name in names:
        cfg = _config(name, num_points=num_points)
        torch.manual_seed(0)
        net = build_network("ancsh", 2, 1, **cfg.network_kwargs())
        opt = torch.optim.Adam(net.parameters())
        steps, cpu = [], []
        for _ in range(repeats + 1):
            s, c = time.perf_counter(), time.process_time()
            loss, _ = ancsh_loss(net(x), t)
            opt.zero_grad()
            loss.backward()
            opt.step()
            steps.append(time.perf_counter() - s)
            cpu.append(time.process_time() - c)
        net.eval()
        fwd, fwd_cpu = [], []
        with torch.no_grad():
            for _ in range(repeats + 1):
                s, c = time.perf_counter(), time.process_time()
                net(x[:1])
                fwd.append(time.perf_counter() - s)
                fwd_cpu.append(time.process_time() - c)
        rows.append({
            "setting": name, "width": cfg.width, "npoints": list(cfg.npoints), "nsamples": list(cfg.nsamples),
            "backbones": cfg.backbones, "params": sum(p.numel() for p in net.parameters()),
            "step_s": float(np.median(steps[1:])), "step_cpu_s": float(np.median(cpu[1:])),
            "forward_ms": 1e3 * float(np.min(fwd[1:])), "forward_cpu_ms": 1e3 * float(np.min(fwd_cpu[1:])),
            "threads": threads, "load_avg": os.getloadavg()[0],
        })
        print(json.dumps(rows[-1]), flush=True)
    return rows


def accuracy(names, data, *, steps: int, frames: int | None = None, seed: int = 0) -> list[dict]:
    """Train each setting for ``steps`` steps on the same frames; validation metrics at the end."""
    from ...learned.training.data import arrays_from_dataset
    from ...learned.training.train import Trainer, split_by_instance

    arrays = arrays_from_dataset(data, 1024, seed=seed)
    if frames is not None:
        arrays = arrays.subset(np.arange(min(frames, len(arrays))))
    train, val = split_by_instance(arrays, 0.1, seed)
    rows = []
    for name in names:
        cfg = _config(name, max_steps=steps, lr_decay_steps=max(1, steps // 2), val_every=steps, checkpoint_every=steps, seed=seed)
        trainer = Trainer(cfg, train, val, None, progress=False)
        t0 = time.perf_counter()
        trainer.fit()
        row = {"setting": name, "steps": steps, "train_min": (time.perf_counter() - t0) / 60}
        row.update({k: v for k, v in trainer.history[-1].items() if k.startswith("val_")})
        rows.append(row)
        print(json.dumps(row), flush=True)
    return rows


def pipeline(data, weights: str, *, frames: int = 10, formulations=("per_part", "soft", "exact_reduced"),
             direct: str | None = None) -> list[dict]:
    """Network + fit on ``frames`` evenly spaced frames of ``data``; mean errors per formulation.

    Camera-space joints: axis angle (deg) and line-line distance (m) of each formulation's fit,
    and, with ``direct`` (direct-voting weights), of the direct-voting baseline.
    """
    from ...data.dataset import FrameDataset
    from ...geometry.lines import line_distance
    from ...geometry.metrics import axis_angle_error_deg, rotation_error_deg, translation_error
    from ...solvers.formulations import provider_fit_config
    from ...solvers import Observation, fit
    from ...learned.inference.provider import LearnedProvider

    ds = FrameDataset(data)
    provider = LearnedProvider(weights)
    voter = None
    if direct is not None:
        from ...learned.inference.provider import DirectVotingPredictor

        voter = DirectVotingPredictor(direct)
    picks = np.linspace(0, len(ds) - 1, frames).round().astype(int)
    recs: dict[str, list] = {f: [] for f in formulations}
    net_s, axis, direct_err = [], [], []

    def joint_errors(axes, pivots, gt):
        return [(axis_angle_error_deg(axes[k], gt.joint_axes_cam[k]),
                 line_distance(pivots[k], axes[k], gt.joint_pivots_cam[k], gt.joint_axes_cam[k]))
                for k in range(len(axes))]

    for i in picks:
        fr = ds[int(i)]
        obs = Observation(fr.points)
        if voter is not None:
            axes, pivots, _ = voter.joints(obs)
            direct_err.append(joint_errors(axes, pivots, fr.gt))
        t0 = time.perf_counter()
        corr = provider.correspond(obs)
        net_s.append(time.perf_counter() - t0)
        axis.append([axis_angle_error_deg(corr.joint_axes_naocs[k], fr.gt.joint_axes_naocs[k]) for k in range(corr.num_joints)])
        for f in formulations:
            t0 = time.perf_counter()
            r = fit(obs, corr, f, config=provider_fit_config(provider))
            dt = time.perf_counter() - t0
            if not r.ok:
                recs[f].append(None)
                continue
            M = corr.num_parts
            rot = [rotation_error_deg(r.T_cam_npcs[j].rotation, fr.gt.T_cam_npcs[j].rotation) for j in range(M)]
            tr = [translation_error(r.T_cam_npcs[j].translation, fr.gt.T_cam_npcs[j].translation) for j in range(M)]
            state = np.abs(r.joint_states - fr.gt.joint_states)
            recs[f].append((rot, tr, state, dt, joint_errors(r.joint_axes_cam, r.joint_pivots_cam, fr.gt)))
    rows = []
    for f, rr in recs.items():
        ok = [r for r in rr if r is not None]
        rows.append({
            "formulation": f, "frames": len(rr), "failures": len(rr) - len(ok),
            "rot_err_deg": np.mean([r[0] for r in ok], axis=0).round(2).tolist() if ok else None,
            "trans_err_m": np.mean([r[1] for r in ok], axis=0).round(4).tolist() if ok else None,
            "state_err": np.mean([r[2] for r in ok], axis=0).round(4).tolist() if ok else None,
            "fit_s": float(np.mean([r[3] for r in ok])) if ok else None,
            "joint_axis_err_deg": np.mean([[e[0] for e in r[4]] for r in ok], axis=0).round(2).tolist() if ok else None,
            "joint_line_dist_m": np.mean([[e[1] for e in r[4]] for r in ok], axis=0).round(4).tolist() if ok else None,
            "network_s": float(np.mean(net_s)), "naocs_axis_err_deg": np.mean(axis, axis=0).round(3).tolist(),
        })
        print(json.dumps(rows[-1]), flush=True)
    if direct_err:
        rows.append({
            "formulation": "direct_voting", "frames": len(direct_err),
            "joint_axis_err_deg": np.mean([[e[0] for e in d] for d in direct_err], axis=0).round(2).tolist(),
            "joint_line_dist_m": np.mean([[e[1] for e in d] for d in direct_err], axis=0).round(4).tolist(),
        })
        print(json.dumps(rows[-1]), flush=True)
    return rows


@dataclass(frozen=True)
class StepVariant:
    """One way to run a training step, for :func:`training_cost`.

    Attributes
    ----------
    name, label : str
    channels_last : bool
        Channel-last layers (else the reference 1x1 convolutions).
    cached : bool
        Neighbourhoods from a per-frame cache (else sampled and grouped in the step).
    batch : int
    threads : int
        torch intra-op threads.
    bf16 : bool
        ``torch.autocast("cpu", torch.bfloat16)`` around the forward pass and the loss.
    compiled : bool
        The network compiled by ``torch.compile`` (:func:`ancsh.learned.training.compiled.compile_network`,
        as ``TrainConfig.compile``); the compilation is timed apart, before the timed repetitions.
    """

    name: str
    label: str
    channels_last: bool = True
    cached: bool = True
    batch: int = 16
    threads: int = 1
    bf16: bool = False
    compiled: bool = False


STEP_VARIANTS = {
    v.name: v
    for v in (
        StepVariant("today", "today's step: 1x1 convolutions, sampling and grouping every step", False, False),
        StepVariant("channels_last", "channel-last layers, sampling and grouping every step", True, False),
        StepVariant("new", "new step: channel-last layers + cached neighbourhoods", True, True),
        StepVariant("new_b8", "new step, batch 8", True, True, batch=8),
        StepVariant("new_b32", "new step, batch 32", True, True, batch=32),
        StepVariant("new_2threads", "new step, 2 threads", True, True, threads=2),
        StepVariant("new_bf16", "new step, bf16 autocast", True, True, bf16=True),
        StepVariant("new_compiled", "new step compiled: torch.compile, inductor C++ kernels", True, True, compiled=True),
    )
}
"""Step variants of ``ancsh bench learned-cost`` by name; ``today`` is the reference, ``new`` the default step."""


def training_cost(variants=tuple(STEP_VARIANTS), *, width: float = 0.5, num_points: int = 1024, repeats: int = 6,
                  seed: int = 0) -> dict:
    """Training-step cost of each :class:`StepVariant`, measured in one process, repetitions interleaved.

    Every variant starts from the same network and optimiser state and trains on the same
    random clouds (``width``, 256/64 centres, 32/32 neighbours: the shipped networks' size). The
    first repetition of each variant is a warm-up and is left out; the process CPU time of a
    step is the cost measure (the machine is shared, so wall times vary with the load).

    Returns
    -------
    dict
        ``rows`` (one per variant: ``frames_per_cpu_s``, ``frames_per_wall_s``, medians of
        ``step_cpu_s`` / ``step_wall_s``, ``first_loss``; compiled variants also ``compile_cpu_s`` /
        ``compile_wall_s``, the first step's time, compilation included), ``cache_ms_per_frame`` (CPU
        time to compute the neighbourhoods of one frame, once per frame), ``forward_ms`` (one frame,
        one thread, eval mode, per layout: min CPU time), ``first_loss_float64`` (the first step's loss of the
        reference variant's batch in float64) and the settings.
    """
    import torch

    from ...learned.network.config import TrainConfig
    from ...learned.training.losses import Targets, ancsh_loss
    from ...learned.training.compiled import compile_network
    from ...learned.network.models import build_network
    from ...learned.network.pointnet2 import Neighbourhoods

    variants = [STEP_VARIANTS[v] if isinstance(v, str) else v for v in variants]
    if isinstance(repeats, bool) or not isinstance(repeats, int) or repeats < 2:
        raise ValueError(f"repeats: expected an integer >= 2, got {repeats!r}")
    threads_before = torch.get_num_threads()
    cfg = TrainConfig(width=width, num_points=num_points)
    g = torch.Generator().manual_seed(seed)
    F = max(v.batch for v in variants)
    x = torch.randn(F, num_points, 3, generator=g) * torch.tensor([0.2, 0.1, 0.15]) + torch.tensor([0.0, 0.0, 1.5])
    targets = Targets(
        torch.randint(0, 2, (F, num_points), generator=g), torch.rand(F, num_points, 3, generator=g),
        torch.rand(F, num_points, generator=g) + 0.5, torch.rand(F, num_points, 3, generator=g),
        torch.randint(0, 2, (F, num_points), generator=g), torch.rand(F, num_points, 7, generator=g),
        torch.ones(F, num_points, 7), torch.rand(F, num_points, 7, generator=g),
    )
    torch.manual_seed(seed)
    base = build_network("ancsh", 2, 1, **cfg.network_kwargs())
    torch.set_num_threads(1)
    c0 = time.process_time()
    cache = Neighbourhoods.from_numpy(base.neighbourhoods(x).numpy())
    cache_ms = 1e3 * (time.process_time() - c0) / F
    ref_batch = next((v.batch for v in variants if v.name == "today"), variants[0].batch)
    with torch.no_grad():  # the first step's loss in float64: what the float32 first losses round
        net64, sl = copy.deepcopy(base).double(), slice(0, ref_batch)
        nb64 = cache.map(lambda v: v[sl].double() if v.is_floating_point() else v[sl])
        t64 = targets[sl]
        t64 = type(t64)(**{k: v.double() if v.is_floating_point() else v for k, v in vars(t64).items()})
        loss64 = ancsh_loss(net64(x[sl].double(), nb64), t64)[0].item()
    states = {}
    for v in variants:
        net = copy.deepcopy(base)
        net.backbone.channels_last = v.channels_last
        states[v.name] = (compile_network(net) if v.compiled else net, torch.optim.Adam(net.parameters(), lr=cfg.lr))
    times: dict[str, list] = {v.name: [] for v in variants}
    first_loss, compile_s = {}, {}

    def step(v):
        net, opt = states[v.name]
        torch.set_num_threads(v.threads)
        idx = slice(0, v.batch)
        nb = None
        if v.cached:
            nb = cache.map(lambda v: v[idx])
        t_wall, t_cpu = time.perf_counter(), time.process_time()
        with torch.autocast("cpu", dtype=torch.bfloat16, enabled=v.bf16):
            loss, _ = ancsh_loss(net(x[idx], nb), targets[idx])
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()
        first_loss.setdefault(v.name, loss.item())
        return time.process_time() - t_cpu, time.perf_counter() - t_wall

    try:
        for v in variants:
            if v.compiled:  # the one-off compilation, apart from the timed steps
                compile_s[v.name] = step(v)
        for _ in range(repeats):
            for v in variants:
                times[v.name].append(step(v))
        forward = {}
        torch.set_num_threads(1)
        for layout, channels_last in (("reference", False), ("channels_last", True)):
            net = copy.deepcopy(base).eval()
            net.backbone.channels_last = channels_last
            cpu = []
            with torch.no_grad():
                for _ in range(repeats + 1):
                    c = time.process_time()
                    net(x[:1])
                    cpu.append(time.process_time() - c)
            forward[layout] = 1e3 * float(np.min(cpu[1:]))
    finally:
        torch.set_num_threads(threads_before)
    rows = []
    for v in variants:
        cpu = float(np.median([t[0] for t in times[v.name][1:]]))
        wall = float(np.median([t[1] for t in times[v.name][1:]]))
        rows.append({**asdict(v), "step_cpu_s": cpu, "step_wall_s": wall, "frames_per_cpu_s": v.batch / cpu,
                     "frames_per_wall_s": v.batch / wall, "first_loss": first_loss[v.name]})
        if v.name in compile_s:
            rows[-1]["compile_cpu_s"], rows[-1]["compile_wall_s"] = compile_s[v.name]
    ref = next((r for r in rows if r["name"] == "today"), rows[0])
    for r in rows:
        r["speedup_cpu"] = r["frames_per_cpu_s"] / ref["frames_per_cpu_s"]
    return {
        "rows": rows, "cache_ms_per_frame": cache_ms, "forward_ms": forward, "reference": ref["name"],
        "first_loss_float64": {"batch": ref_batch, "loss": loss64},
        "settings": {"width": width, "num_points": num_points, "npoints": list(cfg.npoints), "nsamples": list(cfg.nsamples),
                     "repeats": repeats, "seed": seed, "torch": torch.__version__, "cpus": os.cpu_count(),
                     "machine": platform.machine(), "load_avg": os.getloadavg()[0]},
    }
