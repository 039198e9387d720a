"""A short check that the network trains and predicts on a GPU as on the CPU.

``python -m ancsh.cli.bench.gpu_check`` (or ``ancsh bench gpu-check``) on a machine with a CUDA device:

1. trains a small network for a few steps from the same seed on the CPU and on the device and
   compares the per-step losses and the weights;
2. renders a held-out laptop frame and runs the shipped network through the learned provider on
   both (segmentation agreement, NPCS difference) and the ``exact_reduced`` fit of each.

It prints the figures with their tolerances and exits with 1 when one is exceeded. The tolerances
are those of float32 arithmetic in another order (GPU kernels sum differently), not of equality.
``--device cpu`` runs the same comparison CPU against CPU (a smoke test of the script itself).
"""

from __future__ import annotations

import time

import numpy as np

__all__ = ["compare_training", "compare_prediction"]

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
        result = fit(obs, inference.correspondences, "exact_reduced", config=provider.fit_config(), rng=0)
        out[name] = (inference, result, network_s)
    (ia, ra, ta), (ib, rb, tb) = out["cpu"], out["device"]
    rot = [float(np.degrees(rotation_angle(Ta.rotation.T @ Tb.rotation))) for Ta, Tb in zip(ra.T_cam_npcs, rb.T_cam_npcs)]
    return {
        "seg_agreement": float(np.mean(ia.prediction.seg_prob.argmax(1) == ib.prediction.seg_prob.argmax(1))),
        "npcs_max_diff": float(np.abs(ia.prediction.npcs - ib.prediction.npcs).max()),
        "fit_rotation_diff_deg": max(rot) if ra.ok and rb.ok else float("nan"),
        "fits_ok": (ra.ok, rb.ok), "cpu_network_s": ta, "device_network_s": tb,
    }
