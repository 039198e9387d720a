"""Benchmarks of the network size against cost and accuracy (prints numbers, asserts nothing).

``python -m ancsh.studies.learned_cost timing`` -- training-step and single-frame forward times for
several widths / sampling settings (batch 16, 1024 points by default).

``python -m ancsh.studies.learned_cost accuracy --data DIR --steps S`` -- short equal-step training
runs at several widths on the same data, validation metrics on held-out instances.

``python -m ancsh.studies.learned_cost pipeline --data DIR --weights laptop`` -- the learned provider
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

import argparse
import copy
import datetime
import json
import os
import platform
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

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
    from ..learned.network.config import TrainConfig

    width, npoints, nsamples, backbones = SETTINGS[name]
    return TrainConfig(width=width, npoints=npoints, nsamples=nsamples, backbones=backbones, **kw)


def timing(names, *, batch: int = 16, num_points: int = 1024, threads: int = 1, repeats: int = 4) -> list[dict]:
    """Median training-step time (batch ``batch``) and single-frame forward time per setting.

    Wall and process CPU times are both reported: on a shared machine the CPU time of a
    one-thread run is the cost the network itself needs.
    """
    import torch

    from ..learned.training.losses import Targets, ancsh_loss
    from ..learned.network.models import build_network

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
    from ..learned.training.data import arrays_from_dataset
    from ..learned.training.train import Trainer, split_by_instance

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
    from ..data.dataset import FrameDataset
    from ..geometry.lines import line_distance
    from ..geometry.metrics import axis_angle_error_deg, rotation_error_deg, translation_error
    from ..solvers import Observation, fit
    from ..learned.inference.provider import LearnedProvider

    ds = FrameDataset(data)
    provider = LearnedProvider(weights)
    voter = None
    if direct is not None:
        from ..learned.inference.provider import DirectVotingPredictor

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
            r = fit(obs, corr, f)
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

    from ..learned.network.config import TrainConfig
    from ..learned.training.losses import Targets, ancsh_loss
    from ..learned.training.compiled import compile_network
    from ..learned.network.models import build_network
    from ..learned.network.pointnet2 import Neighbourhoods

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
        nb64 = Neighbourhoods(**{k: v[sl].double() if v.is_floating_point() else v[sl] for k, v in vars(cache).items()})
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
            nb = Neighbourhoods(**{k: getattr(cache, k)[idx] for k in asdict(cache)})
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


def write_cost_report(result: dict, path, *, command: str) -> Path:
    """Write :func:`training_cost` output as Markdown to ``path`` (and the numbers as JSON beside it)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    s = result["settings"]
    date = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    lines = [
        "# Training cost of the ANCSH network on a CPU",
        "",
        f"Command: `{command}`  ",
        f"Date: {date}; torch {s['torch']}, {s['machine']}, {s['cpus']} CPUs, load average {s['load_avg']:.1f} at the end  ",
        f"Network: width {s['width']}, {s['num_points']} points, {s['npoints'][0]}/{s['npoints'][1]} centres, "
        f"{s['nsamples'][0]}/{s['nsamples'][1]} neighbours, one backbone (the shipped networks' size); one process, "
        f"{s['repeats']} repetitions per variant interleaved (the first a warm-up), medians.",
        "",
        "Frames per CPU-second = batch / process CPU time of one step (forward, loss, backward, Adam); the machine "
        "is shared, so only ratios measured side by side in one run mean something.",
        "",
        "| Step | batch | threads | step CPU (s) | step wall (s) | frames / CPU-s | frames / wall-s | vs today (CPU) | first loss |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in result["rows"]:
        lines.append(f"| {r['label']} | {r['batch']} | {r['threads']} | {r['step_cpu_s']:.3f} | {r['step_wall_s']:.3f} "
                     f"| {r['frames_per_cpu_s']:.1f} | {r['frames_per_wall_s']:.1f} | {r['speedup_cpu']:.2f}x | {r['first_loss']:.5f} |")
    f = result["forward_ms"]
    lines += [
        "",
        f"Neighbourhood cache: {result['cache_ms_per_frame']:.1f} ms CPU per frame, computed once per frame "
        "(on first load; saved in the run directory), not at every step.",
        "",
        f"Forward pass of one frame ({s['num_points']} points, one thread, eval mode, min CPU time): "
        f"{f['channels_last']:.1f} ms channel-last (sampling and grouping included), {f['reference']:.1f} ms with the reference layers.",
        "",
    ]
    rows = {r["name"]: r for r in result["rows"]}
    for r in result["rows"]:
        if "compile_cpu_s" in r:
            lines += [
                f"Compilation ({r['label']}): the first step took {r['compile_cpu_s']:.0f} s CPU ({r['compile_wall_s']:.0f} s "
                "wall), compilation included; once per process, timed apart from the repetitions. Inductor keeps the "
                "generated kernels on disk (`$TORCHINDUCTOR_CACHE_DIR`, by default `/tmp/torchinductor_<user>`), so a later "
                "process with the same shapes (a resumed run) reuses them. Prediction stays uncompiled (the forward time above).",
                "",
            ]
            if "new" in rows:
                lines += [f"Compiled against uncompiled new step: {rows['new']['step_cpu_s'] / r['step_cpu_s']:.2f}x "
                          "frames per CPU-second.", ""]
    f64 = result["first_loss_float64"]
    lines += [f"First loss of batch {f64['batch']} evaluated in float64 (the same weights and frames): {f64['loss']:.5f}; "
              "the float32 first losses of that batch differ from it by rounding only: "
              + ", ".join(f"{r['name']} {abs(r['first_loss'] - f64['loss']) / abs(f64['loss']):.1e}"
                          for r in result["rows"] if r["batch"] == f64["batch"] and not r["bf16"])
              + " relative.", ""]
    ref = rows.get(result["reference"])
    same = [r for r in result["rows"] if not r["bf16"] and ref is not None and r["batch"] == ref["batch"]]
    if same:
        best = max(same, key=lambda r: r["speedup_cpu"])
        lines += [f"Best variant that computes the same function as today's step: {best['label']}, "
                  f"{best['speedup_cpu']:.2f}x today's frames per CPU-second (issue 12 asks for at least 3x).", ""]
    lines += [
        "Accuracy per training frame: the new step is the same network and computes the same function "
        "(`tests/learned/test_learned_step_cost.py` checks, in float64, that its loss, parameter gradients and "
        "batch-norm running statistics equal the reference step's to 1e-8 relative, and that cached neighbourhoods "
        "equal freshly computed ones index for index); so does the compiled step (the same file checks the network "
        "traced by torch.compile, with dynamo alone and with inductor's C++ kernels; compiled, each set abstraction "
        "max-pools before its last batch norm + ReLU, which are monotone per channel: the same values). The bf16 and batch variants change the numerics or the "
        "optimisation and would need an equal-frames training comparison before use.",
        "",
    ]
    path.write_text("\n".join(lines))
    path.with_suffix(".json").write_text(json.dumps(result, indent=1) + "\n")
    return path


def ablation(runs: dict, *, frames: int = 300, seed: int = 0, checkpoints=("last.pt", "best.pt"),
             baseline: str | None = None) -> dict:
    """Held-out test errors of training runs (e.g. paper loss vs paper + pose loss) through the full pipeline.

    Parameters
    ----------
    runs : dict of str -> path
        Name -> run directory of ``ancsh train`` (``config.json``, ``history.csv``, checkpoints).
    frames : int
        Rendered test frames (held-out instances, :func:`ancsh.studies.table1.evaluate_category`).
    checkpoints : sequence of str
        Checkpoint files of each run to evaluate (missing ones are skipped).
    baseline : str, optional
        Weights the runs started from, evaluated first on the same frames as a row ``start``: ``"builtin"``
        (the shipped network of the runs' category) or a weights file / checkpoint. Fine-tunes are judged
        against it.

    Returns
    -------
    dict
        ``rows``: the baseline's row first (its training columns ``None``), then per run and checkpoint, its step, the run's training steps and training wall time,
        and means of the ``exact_reduced`` fit's per-part rotation error, joint-axis and joint-state
        errors and of the network's per-part NPCS orientation error (the error budget). ``curves``:
        per run, the pose validation of its history (``step``, ``pose_score`` = mean fitted rotation +
        joint-axis error in degrees on the run's validation instances, ``val_npcs_err``), for an
        equal-step comparison along training.
    """
    import csv

    from ..learned.network.config import TrainConfig
    from .table1 import evaluate_category, summarize
    from ..learned.network.weights import load_network

    rows, curves = [], {}
    if not runs:
        raise ValueError("runs: expected at least one NAME -> run directory")

    def row(name, category, weights, checkpoint, extra):
        ev = evaluate_category(category, frames=frames, methods=("exact_reduced",), weights=weights, seed=seed,
                               progress=False)
        sm = summarize(ev)
        m = sm["methods"]["exact_reduced"]
        rows.append({
            "run": name, **extra, "checkpoint": checkpoint, "category": category,
            "step": load_network(category if weights is None else weights).step,
            "frames": m["frames"], "failures": m["failures"], "rot_deg": m["rot_deg"]["mean"],
            "rot_deg_median": m["rot_deg"]["median"], "axis_deg": m["axis_deg"]["mean"], "state_err": m["state_err"]["mean"],
            "npcs_rot_deg": sm["budget"]["npcs_rot_deg"]["mean"],
        })
        print(json.dumps(rows[-1]), flush=True)

    if baseline is not None:
        category = TrainConfig.from_json(Path(next(iter(runs.values()))) / "config.json").category
        weights = None if baseline == "builtin" else Path(baseline)
        if weights is not None and not weights.is_file():
            raise ValueError(f"baseline: no weights file {weights}")
        row("start", category, weights, "shipped" if weights is None else weights.name,
            {"run_dir": None, "pose_weight": None, "augment_deg": None, "pose_start_step": None, "trained_steps": None,
             "train_wall_min": None})
    for name, run in runs.items():
        run = Path(run)
        config = TrainConfig.from_json(run / "config.json")
        with open(run / "history.csv", newline="") as f:
            hist = list(csv.DictReader(f))
        curves[name] = [{"step": int(float(h["step"])), "pose_score": float(h["pose_score"]),
                         "val_npcs_err": float(h["val_npcs_err"]) if h.get("val_npcs_err") else None}
                        for h in hist if h.get("pose_score")]
        for ck in checkpoints:
            if not (run / ck).is_file():
                continue
            row(name, config.category, run / ck, ck, {
                "run_dir": str(run), "pose_weight": config.pose_weight,
                "augment_deg": [config.augment_roll_deg, config.augment_tilt_deg], "pose_start_step": config.pose_start_step,
                "trained_steps": int(float(hist[-1]["step"])), "train_wall_min": float(hist[-1]["elapsed_s"]) / 60})
    return {"rows": rows, "curves": curves, "frames": frames, "seed": seed, "baseline": baseline}


def write_ablation_report(result: dict, path, *, command: str, commands=()) -> Path:
    """Write :func:`ablation` output as Markdown to ``path`` (JSON beside it); ``commands``: how the runs were made."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    date = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")

    def fmt(v, spec=".2f"):
        return ", ".join("-" if x is None else format(x, spec) for x in v)

    lines = [
        "# Training ablation at equal training time (pose-aware loss, rotation augmentation)",
        "",
        f"Command: `{command}`  ",
        f"Date: {date}; {result['frames']} rendered test frames (held-out instances, seed {result['seed']}) per row, "
        "fit `exact_reduced`; means over frames (failed fits left out and counted).",
        "",
    ]
    if commands:
        lines += ["Training runs:", "", *[f"- `{c}`" for c in commands], ""]
    lines += [
        "| Run | pose weight | augmentation roll / tilt (°) | checkpoint (step) | steps trained | training wall (min) "
        "| rotation error per part (°) | median rotation (°) | joint axis (°) | joint state "
        "| NPCS orientation error per part (°) | failed fits |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    def opt(v, spec="g"):
        return "-" if v is None else format(v, spec)

    for r in result["rows"]:
        a = r.get("augment_deg", (0.0, 0.0))  # None: the baseline row (no training of its own)
        aug = "-" if a is None else f"{a[0]:g} / {a[1]:g}"
        lines.append(
            f"| {r['run']} | {opt(r['pose_weight'])} | {aug} | {r['checkpoint']} ({r['step']}) | {opt(r['trained_steps'])} "
            f"| {opt(r['train_wall_min'], '.1f')} | {fmt(r['rot_deg'])} | {fmt(r['rot_deg_median'])} | {fmt(r['axis_deg'])} "
            f"| {fmt(r['state_err'])} | {fmt(r['npcs_rot_deg'])} | {r['failures']}/{r['frames']} |")
    lines.append("")
    lines += _curve_table(result.get("curves") or {}, {r["run"]: r for r in result["rows"]})
    path.write_text("\n".join(lines))
    path.with_suffix(".json").write_text(json.dumps(result, indent=1) + "\n")
    return path


def _curve_table(curves: dict, rows: dict) -> list[str]:
    """Markdown: the runs' pose validation at equal steps (their histories), one column per run."""
    steps = sorted({c["step"] for curve in curves.values() for c in curve})
    if not steps:
        return []
    names = list(curves)

    def label(n):
        r = rows.get(n)
        return n if r is None else f"{n} (pose weight {r['pose_weight']:g} from step {r.get('pose_start_step', 0)})"

    lines = ["## Pose validation along training (equal steps)", "",
             "From each run's history: the pose score (mean fitted rotation + joint-axis error, degrees, `exact_reduced`, "
             "on frames of the run's own *validation* instances, the score that selects `best.pt`) and, in brackets, "
             "the validation NPCS error; runs that share a start share their first rows.", "",
             "| step | " + " | ".join(label(n) for n in names) + " |", "|---|" + "---|" * len(names)]
    for st in steps:
        cells = []
        for n in names:
            c = next((c for c in curves[n] if c["step"] == st), None)
            cells.append("" if c is None else f"{c['pose_score']:.2f}" + (
                "" if c["val_npcs_err"] is None else f" ({c['val_npcs_err']:.3f})"))
        lines.append(f"| {st} | " + " | ".join(cells) + " |")
    return lines + [""]


def roll_equivariance(networks: dict, *, frames: int = 30, angle_deg: float = 10.0, seed: int = 0) -> dict:
    """:func:`ancsh.studies.equivariance.roll_gain` of several networks on the same test frames.

    ``networks``: label -> ``(category, weights or None)`` (``None``: the shipped network of the category).
    """
    from .equivariance import roll_gain

    rows = {}
    for label, (category, weights) in networks.items():
        rows[label] = roll_gain(category, weights, frames=frames, angle_deg=angle_deg, seed=seed)
        print(f"{label}: gain {rows[label]['gain_mean']:.2f} ± {rows[label]['gain_sem']:.2f}", flush=True)
    for category in dict.fromkeys(c for c, _ in networks.values()):  # the measurement's reference: gain 1
        rows[f"{category}: ground truth"] = roll_gain(category, frames=frames, angle_deg=angle_deg, seed=seed, oracle=True)
    return {"rows": rows, "frames": frames, "angle_deg": angle_deg, "seed": seed}


def write_roll_report(result: dict, path, *, command: str) -> Path:
    """Write :func:`roll_equivariance` output as Markdown to ``path`` (JSON beside it)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    date = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    lines = [
        "# Camera-roll equivariance of the networks", "",
        f"Command: `{command}`  ",
        f"Date: {date}; {result['frames']} rendered test frames per network (held-out instances, seed {result['seed']}), "
        f"each fitted (`exact_reduced`) as rendered and after a camera roll of ±{result['angle_deg']:g}° about the ray "
        "through the points' centroid (alternating sign).", "",
        "A camera roll turns the true part rotations by exactly the roll, so the fitted rotations of a network that reads "
        "the orientation from the object's shape follow it (gain 1). A gain below 1 is the share the network follows: "
        "the rest it takes from the camera frame (the object's usual orientation in the training views), and on test "
        "views it is biased toward that usual orientation (`ancsh.studies.equivariance`). Gain: the fitted rotation's "
        "turn about the roll axis over the roll, averaged over parts, then over frames (± its standard error). The "
        "*ground truth* rows fit the true correspondences of the same frames: the measurement's reference.", "",
        "| network | category | weights (sha256) | frames (skipped) | gain mean ± s.e. | median |",
        "|---|---|---|---|---|---|",
    ]
    for label, r in result["rows"].items():
        lines.append(f"| {label} | {r['category']} | `{Path(r['weights']).name}` ({(r['weights_sha256'] or '-')[:12]}) "
                     f"| {r['frames']} ({r['skipped']}) | {r['gain_mean']:.2f} ± {r['gain_sem']:.2f} | "
                     f"{r['gain_median']:.2f} |")
    path.write_text("\n".join(lines) + "\n")
    path.with_suffix(".json").write_text(json.dumps(result, indent=1) + "\n")
    return path


def register(sub) -> None:
    """Add ``ancsh bench learned-cost``, ``learned-ablation`` and ``roll-equivariance`` to the ``bench`` sub-parsers."""
    r = sub.add_parser("roll-equivariance", help="how far each network's fitted rotation follows a camera roll "
                       "(1 = reads the shape; less = leans on the camera frame)")
    r.add_argument("--categories", nargs="+", help="shipped networks of these categories (default: every shipped one)")
    r.add_argument("--weights", nargs="*", default=(), metavar="LABEL=CATEGORY:PATH",
                   help="also these weights files or checkpoints (e.g. oven_aug=oven:runs/oven_aug/best.pt)")
    r.add_argument("--frames", type=int, default=30, help="test frames per network (default 30)")
    r.add_argument("--angle", type=float, default=10.0, help="roll in degrees (default 10)")
    r.add_argument("--seed", type=int, default=0)
    r.add_argument("--out", type=Path, help="Markdown file; default: a fresh folder bench_out/roll_equivariance_<UTC time>/")
    r.set_defaults(func=run_roll)
    a = sub.add_parser("learned-ablation", help="held-out errors of training runs through the full pipeline (loss ablation)")
    a.add_argument("--runs", nargs="+", required=True, metavar="NAME=RUN_DIR", help="run directories of `ancsh train`")
    a.add_argument("--frames", type=int, default=300, help="rendered test frames per checkpoint (default 300)")
    a.add_argument("--seed", type=int, default=0)
    a.add_argument("--baseline", metavar="WEIGHTS", help="also evaluate the weights the runs started from, as a row "
                   "'start': 'builtin' (the shipped network of the runs' category) or a weights file")
    a.add_argument("--train-commands", nargs="*", default=(), help="the commands that made the runs (for the report)")
    a.add_argument("--out", type=Path, help="Markdown file (e.g. docs/results/learned_ablation.md); default: a fresh "
                   "folder bench_out/learned_ablation_<UTC time>/")
    a.set_defaults(func=run_ablation)
    p = sub.add_parser("learned-cost", help="training frames per CPU-second: today's step vs the new one (one run)")
    p.add_argument("--variants", nargs="+", default=list(STEP_VARIANTS), choices=list(STEP_VARIANTS))
    p.add_argument("--repeats", type=int, default=6, help="steps per variant, the first a warm-up (default 6)")
    p.add_argument("--width", type=float, default=0.5)
    p.add_argument("--out", type=Path, help="Markdown file (e.g. docs/results/learned_cost.md); default: a fresh "
                   "folder bench_out/learned_cost_<UTC time>/")
    p.set_defaults(func=run_cost)


def run_cost(args) -> int:
    result = training_cost(args.variants, width=args.width, repeats=args.repeats)
    out = args.out or Path("bench_out") / f"learned_cost_{_stamp()}" / "learned_cost.md"
    command = (f"ancsh bench learned-cost --repeats {args.repeats} --width {args.width} --variants {' '.join(args.variants)}"
               + (f" --out {args.out}" if args.out else ""))
    path = write_cost_report(result, out, command=command)
    print(path.read_text())
    print(f"wrote {path}")
    return 0


def run_ablation(args) -> int:
    runs = {}
    for item in args.runs:
        name, sep, run = item.partition("=")
        if not sep or not name or not run:
            raise ValueError(f"--runs: expected NAME=RUN_DIR, got {item!r}")
        runs[name] = run
    result = ablation(runs, frames=args.frames, seed=args.seed, baseline=args.baseline)
    out = args.out or Path("bench_out") / f"learned_ablation_{_stamp()}" / "learned_ablation.md"
    command = (f"ancsh bench learned-ablation --runs {' '.join(args.runs)} --frames {args.frames} --seed {args.seed}"
               + (f" --baseline {args.baseline}" if args.baseline else "") + (f" --out {args.out}" if args.out else ""))
    path = write_ablation_report(result, out, command=command, commands=args.train_commands)
    print(path.read_text())
    print(f"wrote {path}")
    return 0


def run_roll(args) -> int:
    from ..learned.network.weights import shipped_categories

    networks = {c: (c, None) for c in (args.categories if args.categories is not None
                                      else ([] if args.weights else shipped_categories("ancsh")))}
    for item in args.weights:
        label, sep, rest = item.partition("=")
        category, sep2, weights = rest.partition(":")
        if not (sep and sep2 and label and category and weights):
            raise ValueError(f"--weights: expected LABEL=CATEGORY:PATH, got {item!r}")
        networks[label] = (category, weights)
    result = roll_equivariance(networks, frames=args.frames, angle_deg=args.angle, seed=args.seed)
    out = args.out or Path("bench_out") / f"roll_equivariance_{_stamp()}" / "roll_equivariance.md"
    command = " ".join(["ancsh bench roll-equivariance",
                        *(["--categories", *args.categories] if args.categories is not None else []),
                        *(["--weights", *args.weights] if args.weights else []),
                        f"--frames {args.frames} --angle {args.angle:g} --seed {args.seed}",
                        *([f"--out {args.out}"] if args.out else [])])
    path = write_roll_report(result, out, command=command)
    print(path.read_text())
    print(f"wrote {path}")
    return 0


def _stamp() -> str:
    return datetime.datetime.now(datetime.timezone.utc).strftime("%Y%m%d-%H%M%S")


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m ancsh.studies.learned_cost", description=__doc__.split("\n\n")[0])
    sub = p.add_subparsers(dest="what", required=True)
    t = sub.add_parser("timing")
    t.add_argument("--settings", nargs="+", default=list(SETTINGS), choices=list(SETTINGS))
    t.add_argument("--threads", type=int, default=1)
    t.add_argument("--json")
    a = sub.add_parser("accuracy")
    a.add_argument("--data", required=True)
    a.add_argument("--steps", type=int, default=300)
    a.add_argument("--frames", type=int)
    a.add_argument("--settings", nargs="+", default=["w0.125", "w0.25", "w0.5"], choices=list(SETTINGS))
    a.add_argument("--json")
    pl = sub.add_parser("pipeline")
    pl.add_argument("--data", required=True)
    pl.add_argument("--weights", default="laptop", help="category name or weights file")
    pl.add_argument("--frames", type=int, default=10)
    pl.add_argument("--direct", help="direct-voting weights (category name or file) to compare joints with")
    pl.add_argument("--json")
    args = p.parse_args(argv)
    if args.what == "timing":
        rows = timing(args.settings, threads=args.threads)
    elif args.what == "accuracy":
        rows = accuracy(args.settings, args.data, steps=args.steps, frames=args.frames)
    else:
        rows = pipeline(args.data, args.weights, frames=args.frames, direct=args.direct)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(rows, f, indent=1)
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
