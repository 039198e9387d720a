"""A coarse-to-fine cascade of refinement networks, measured side by side (refine_network.md, issue 32).

    .venv/bin/python docs/results/refine_cascade/cascade.py CATEGORY FINE_REFINER FRAMES [OUT.json]

The first FRAMES test frames of CATEGORY (seed 0, as `ancsh evaluate`): the shipped first stage's exact fit, the
shipped refinement network's pass on it (trained on perturbations up to 15 deg), then a second pass either by the same
refiner or by FINE_REFINER (a refinement network fine-tuned on perturbations up to 5 deg, the errors the first pass
leaves). Every row is scored by `ancsh.evaluation.evaluate_fit` on the same frames; prints the mean and median rotation
error per part, the joint axis and state errors, and writes the per-frame errors to OUT.json.
"""

import json
import sys

import numpy as np
import torch

from ancsh.data.generate import FrameGenerator, GenerationConfig
from ancsh.evaluation import evaluate_fit
from ancsh.learned.inference.provider import LearnedProvider
from ancsh.learned.inference.refine_network import refine_with_network
from ancsh.solvers import Observation, fit

ROWS = ("first stage", "1 pass", "2 passes (same refiner)", "1 pass + fine refiner")


def main(category: str, fine: str, frames: int, out: str | None) -> None:
    torch.set_num_threads(1)
    provider = LearnedProvider(category, seed=0, refine="network", refine_passes=1)
    fine_provider = LearnedProvider(category, seed=0, refine="network", refiner=fine).refiner
    gen = FrameGenerator(GenerationConfig(category=category, split="test", seed=0))
    per = {r: [] for r in ROWS}
    for i in range(frames):
        fr = gen.frame(i)
        obs = Observation(fr.points)
        corr = provider.correspond(obs)
        base = fit(obs, corr, "exact_reduced", rng=i)
        if not base.ok:
            continue
        one = provider.refine(obs, corr, base, refine="network", rng=i).result
        two = refine_with_network(provider.refiner, obs, one, rng=i, passes=1).result
        cascade = refine_with_network(fine_provider, obs, one, rng=i, passes=1).result
        for name, r in zip(ROWS, (base, one, two, cascade)):
            ev = evaluate_fit(r, fr.gt, fr.part_names, fr.joint_names).to_dict()
            per[name].append(ev)
        if (i + 1) % 50 == 0:
            print(f"{i + 1}/{frames}", file=sys.stderr, flush=True)
    print(f"{category}, {len(per[ROWS[0]])} frames (`{' '.join(sys.argv)}`)\n")
    print("| row | rotation mean (deg) | rotation median | joint axis (deg) | joint state |\n|---|---|---|---|---|")
    for name in ROWS:
        rot = np.array([[p["rot_deg"] for p in e["parts"]] for e in per[name]], dtype=float)
        axis = np.array([[j["axis_deg"] for j in e["joints"]] for e in per[name]], dtype=float)
        state = np.array([[j["state_err"] for j in e["joints"]] for e in per[name]], dtype=float)
        print(f"| {name} | {', '.join(f'{v:.2f}' for v in np.nanmean(rot, 0))} | "
              f"{', '.join(f'{v:.2f}' for v in np.nanmedian(rot, 0))} | {', '.join(f'{v:.2f}' for v in np.nanmean(axis, 0))} | "
              f"{', '.join(f'{v:.3f}' for v in np.nanmean(state, 0))} |")
    if out:
        json.dump({"command": " ".join(sys.argv), "per_frame": per}, open(out, "w"))


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4] if len(sys.argv) > 4 else None)
