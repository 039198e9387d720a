"""CPU seconds per training step of each lever's configuration, side by side (docs/results/levers_gpu.md).

    .venv/bin/python docs/results/levers_gpu/cpu_cost.py [ROUNDS]

One thread, uncompiled, 1024 points, batch 16, synthetic two-part frames (the step's cost does not depend on the
frames' content); the configurations take turns, ROUNDS (default 4) rounds of 5 steps each after 2 warm-up steps,
and the median round is reported with its ratio to ``base``. ``normals, searched`` is ``normals`` with its points'
nearest points searched in every step, as before they were cached with the neighbourhoods (2026-12-05).
"""

import dataclasses
import json
import sys
import time
from pathlib import Path

import numpy as np
import torch

from ancsh.learned.network.config import TrainConfig
from ancsh.learned.training.data import synthetic_arrays
from ancsh.learned.training.train import Trainer

HERE = Path(__file__).resolve().parent
RUNS = ("base", "normals", "roll30", "pose1", "all")
SEARCHED = "normals, searched"  # normals.json without the cached nearest points (Neighbourhoods.normal_idx)


def main(rounds: int = 4) -> None:
    torch.set_num_threads(1)
    arrays = synthetic_arrays(64, 1024, seed=0, num_parts=2, joint_types="revolute", instances=4)
    trainers = {}
    for run in (*RUNS, SEARCHED):
        cfg = TrainConfig.from_json(HERE / f"{'normals' if run == SEARCHED else run}.json")
        cfg = dataclasses.replace(cfg, num_threads=1, compile=False, val_every=10**6, checkpoint_every=10**6)
        trainers[run] = t = Trainer(cfg, arrays, progress=False)
        if run == SEARCHED:
            del t.neighbourhoods["normal_idx"]
        for _ in range(2):
            t.train_step()
    times = {run: [] for run in trainers}
    for _ in range(rounds):
        for run, t in trainers.items():
            start = time.process_time()
            for _ in range(5):
                t.train_step()
            times[run].append((time.process_time() - start) / 5)
    base = np.median(times["base"])
    print("| configuration | CPU s / step (one thread) | x base |\n|---|---|---|")
    for run in trainers:
        m = np.median(times[run])
        print(f"| {run} | {m:.2f} | {m / base:.2f} |")
    print("\n" + json.dumps({k: [round(x, 3) for x in v] for k, v in times.items()}))


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 4)
