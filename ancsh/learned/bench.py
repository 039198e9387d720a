"""Benchmarks of the network size against cost and accuracy (prints numbers, asserts nothing).

``python -m ancsh.learned.bench timing`` -- training-step and single-frame forward times for
several widths / sampling settings (batch 16, 1024 points by default).

``python -m ancsh.learned.bench accuracy --data DIR --steps S`` -- short equal-step training
runs at several widths on the same data, validation metrics on held-out instances.

``python -m ancsh.learned.bench pipeline --data DIR --weights laptop`` -- the learned provider
followed by each fitting formulation on test frames: per-part rotation/translation errors,
joint-state error, and the time of the network and of each fit.

Results go to stdout as a markdown table (and ``--json`` to a file).
"""

from __future__ import annotations

import argparse
import json
import os
import time

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
    from .config import TrainConfig

    width, npoints, nsamples, backbones = SETTINGS[name]
    return TrainConfig(width=width, npoints=npoints, nsamples=nsamples, backbones=backbones, **kw)


def timing(names, *, batch: int = 16, num_points: int = 1024, threads: int = 1, repeats: int = 4) -> list[dict]:
    """Median training-step time (batch ``batch``) and single-frame forward time per setting.

    Wall and process CPU times are both reported: on a shared machine the CPU time of a
    one-thread run is the cost the network itself needs.
    """
    import torch

    from .losses import Targets, ancsh_loss
    from .network import build_network

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
    from .data import arrays_from_dataset
    from .train import Trainer, split_by_instance

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
    from .provider import LearnedProvider

    ds = FrameDataset(data)
    provider = LearnedProvider(weights)
    voter = None
    if direct is not None:
        from .provider import DirectVotingPredictor

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


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m ancsh.learned.bench", description=__doc__.split("\n\n")[0])
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
