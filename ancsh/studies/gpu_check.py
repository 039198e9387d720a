"""A short check that the network trains and predicts on a GPU as on the CPU.

``python -m ancsh.studies.gpu_check`` (or ``ancsh bench gpu-check``) on a machine with a CUDA device:

1. trains a small network for a few steps from the same seed on the CPU and on the device and
   compares the per-step losses and the weights;
2. renders a held-out laptop frame and runs the shipped network through the learned provider on
   both (segmentation agreement, NPCS difference) and the ``exact_reduced`` fit of each.

It prints the figures with their tolerances and exits with 1 when one is exceeded. The tolerances
are those of float32 arithmetic in another order (GPU kernels sum differently), not of equality.
``--device cpu`` runs the same comparison CPU against CPU (a smoke test of the script itself).
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np

__all__ = ["compare_training", "compare_prediction", "main", "register_bench"]

LOSS_RTOL_FIRST_STEP = 1e-4
"""Relative loss difference allowed at the first step (same weights, same batch: rounding only)."""
SEG_AGREEMENT_MIN = 0.99
NPCS_MAX_DIFF = 1e-3
ROTATION_DIFF_MAX_DEG = 0.5


def compare_training(device, *, steps: int = 5, seed: int = 0) -> dict:
    """Train the same small network ``steps`` steps on the CPU and on ``device``; losses, weights, times."""
    import torch

    from ..learned.network.config import TrainConfig
    from ..learned.training.data import synthetic_arrays
    from ..learned.training.train import Trainer

    arrays = synthetic_arrays(16, 256, seed=seed, num_parts=2, joint_types="revolute", instances=2)
    config = TrainConfig(num_points=256, width=0.25, npoints=(64, 16), nsamples=(16, 16), batch_size=8,
                         max_steps=steps, val_every=10_000, checkpoint_every=10_000, seed=seed, num_threads=1)
    out = {}
    for name, dev in (("cpu", "cpu"), ("device", device)):
        trainer = Trainer(config, arrays, progress=False, device=dev)
        t0 = time.perf_counter()
        losses = trainer.fit(steps)
        if trainer.device.type == "cuda":
            torch.cuda.synchronize()
        out[name] = {"losses": [row["total"] for row in losses], "s_per_step": (time.perf_counter() - t0) / steps,
                     "weights": {k: v.detach().cpu().double() for k, v in trainer.model.state_dict().items()}}
    a, b = out["cpu"], out["device"]
    diffs = [abs(x - y) / max(abs(x), 1e-12) for x, y in zip(a["losses"], b["losses"])]
    w = max(float((a["weights"][k] - b["weights"][k]).abs().max()) for k in a["weights"])
    return {"loss_rel_diff": diffs, "weights_max_diff": w, "cpu_s_per_step": a["s_per_step"],
            "device_s_per_step": b["s_per_step"], "losses_cpu": a["losses"], "losses_device": b["losses"]}


def compare_prediction(device, *, category: str = "laptop", frame: int = 0) -> dict:
    """The shipped network and the ``exact_reduced`` fit on one rendered test frame, on the CPU and on ``device``."""
    from ..data.generate import FrameGenerator, GenerationConfig
    from ..geometry.rotations import rotation_angle
    from ..solvers import Observation, fit
    from ..learned.inference.provider import LearnedProvider
    from ..learned.network.weights import load_network

    fr = FrameGenerator(GenerationConfig(category=category, split="test")).frame(frame)
    obs = Observation(fr.points)
    out = {}
    for name, dev in (("cpu", "cpu"), ("device", device)):
        provider = LearnedProvider(load_network(category), device=dev)
        t0 = time.perf_counter()
        inference = provider.infer(obs)
        network_s = time.perf_counter() - t0
        result = fit(obs, inference.correspondences, "exact_reduced", rng=0)
        out[name] = (inference, result, network_s)
    (ia, ra, ta), (ib, rb, tb) = out["cpu"], out["device"]
    rot = [float(np.degrees(rotation_angle(Ta.rotation.T @ Tb.rotation))) for Ta, Tb in zip(ra.T_cam_npcs, rb.T_cam_npcs)]
    return {
        "seg_agreement": float(np.mean(ia.prediction.seg_prob.argmax(1) == ib.prediction.seg_prob.argmax(1))),
        "npcs_max_diff": float(np.abs(ia.prediction.npcs - ib.prediction.npcs).max()),
        "fit_rotation_diff_deg": max(rot) if ra.ok and rb.ok else float("nan"),
        "fits_ok": (ra.ok, rb.ok), "cpu_network_s": ta, "device_network_s": tb,
    }


def run(args: argparse.Namespace) -> int:
    import torch

    from ..learned.devices import resolve_device

    device = resolve_device(args.device, argument="--device")
    name = torch.cuda.get_device_name(device) if device.type == "cuda" else "CPU"
    print(f"ancsh GPU check: {device} ({name}) against the CPU; torch {torch.__version__}")
    failures = []
    t = compare_training(device, steps=args.steps)
    print(f"training, {args.steps} steps: loss relative difference per step "
          + " ".join(f"{d:.1e}" for d in t["loss_rel_diff"])
          + f"; weights max difference {t['weights_max_diff']:.2e}; "
          f"s/step cpu {t['cpu_s_per_step']:.3f}, {device.type} {t['device_s_per_step']:.3f}")
    if not t["loss_rel_diff"][0] <= LOSS_RTOL_FIRST_STEP:
        failures.append(f"first-step loss differs by {t['loss_rel_diff'][0]:.1e} > {LOSS_RTOL_FIRST_STEP:.0e}")
    if not all(np.isfinite(t["losses_device"])):
        failures.append("non-finite loss on the device")
    p = compare_prediction(device)
    print(f"prediction ({'laptop'} test frame 0): segmentation agreement {p['seg_agreement']:.4f}, NPCS max difference "
          f"{p['npcs_max_diff']:.1e}, exact_reduced rotation difference {p['fit_rotation_diff_deg']:.3f} deg "
          f"(fits ok: {p['fits_ok']}); network s cpu {p['cpu_network_s']:.3f}, {device.type} {p['device_network_s']:.3f}")
    if not p["seg_agreement"] >= SEG_AGREEMENT_MIN:
        failures.append(f"segmentation agreement {p['seg_agreement']:.4f} < {SEG_AGREEMENT_MIN}")
    if not p["npcs_max_diff"] <= NPCS_MAX_DIFF:
        failures.append(f"NPCS difference {p['npcs_max_diff']:.1e} > {NPCS_MAX_DIFF:.0e}")
    if not p["fit_rotation_diff_deg"] <= ROTATION_DIFF_MAX_DEG:
        failures.append(f"fitted rotations differ by {p['fit_rotation_diff_deg']:.3f} deg > {ROTATION_DIFF_MAX_DEG}")
    print("PASS" if not failures else "FAIL: " + "; ".join(failures))
    return 0 if not failures else 1


def _parser(parser: argparse.ArgumentParser) -> argparse.ArgumentParser:
    parser.add_argument("--device", default="cuda", help="device to check against the CPU (default cuda; cpu = smoke test)")
    parser.add_argument("--steps", type=int, default=5, help="training steps (default 5)")
    parser.set_defaults(func=run)
    return parser


def register_bench(bench_sub) -> None:
    """``ancsh bench gpu-check``."""
    _parser(bench_sub.add_parser("gpu-check", help="train a few steps and predict on a CUDA device and on the CPU; "
                                 "compare (run it on a machine with a GPU)"))


def main(argv=None) -> int:
    args = _parser(argparse.ArgumentParser(prog="python -m ancsh.studies.gpu_check", description=__doc__.split("\n\n")[0]))
    args = args.parse_args(argv)
    try:
        return run(args)
    except ValueError as exc:
        print(f"gpu_check: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
