"""What the refinement network adds per frame with 1 and with 2 passes, measured side by side (refine_network.md).

    .venv/bin/python docs/results/refine_passes/cost.py FRAMES CATEGORY [CATEGORY ...]

For each category the first FRAMES test frames (seed 0, as `ancsh evaluate`): the first stage's exact fit once, then
the shipped refinement network's refinement of it with 1 and with 2 passes, the two in alternating order frame by
frame, on one thread. Prints per category the median milliseconds each adds to the first stage, and the first
stage's own median (network pass + fit).
"""

import sys
import time

import numpy as np
import torch

from ancsh.data.generate import FrameGenerator, GenerationConfig
from ancsh.learned.inference.provider import LearnedProvider
from ancsh.solvers import Observation, fit


def main(frames: int, categories) -> None:
    torch.set_num_threads(1)
    print("| category | first stage (ms) | + 1 pass (ms) | + 2 passes (ms) | passes run with 2 (mean) |\n|---|---|---|---|---|")
    for cat in categories:
        one = LearnedProvider(cat, seed=0, refine="network", refine_passes=1)
        two = LearnedProvider(cat, seed=0, refine="network", refine_passes=2)
        gen = FrameGenerator(GenerationConfig(category=cat, split="test", seed=0))
        first, t1, t2, runs = [], [], [], []
        for i in range(frames):
            obs = Observation(gen.frame(i).points)
            s = time.perf_counter()
            r = fit(obs, one.correspond(obs), "exact_reduced", rng=i)
            first.append(time.perf_counter() - s)
            if not r.ok:
                continue
            order = (one, two) if i % 2 == 0 else (two, one)
            for p in order:
                s = time.perf_counter()
                out = p.refine(obs, None, r, refine="network", rng=i)
                (t1 if p is one else t2).append(time.perf_counter() - s)
                if p is two:
                    runs.append(out.passes)
        print(f"| {cat} | {1e3 * np.median(first):.0f} | {1e3 * np.median(t1):.0f} | {1e3 * np.median(t2):.0f} "
              f"| {np.mean(runs):.2f} |", flush=True)


if __name__ == "__main__":
    main(int(sys.argv[1]), sys.argv[2:])
