"""The first stage's and the refinement network's outputs averaged: an ensemble of two networks at no extra cost
(refine_network.md, issue 32).

    .venv/bin/python docs/results/refine_ensemble/ensemble.py CATEGORY FRAMES W1,W2,...

The first FRAMES test frames of CATEGORY (seed 0, as `ancsh evaluate`): the shipped first stage's exact fit; one pass
of the shipped refinement network on it; the same fit on the per-point average ``(1 - w) first + w refiner`` of the
two networks' raw outputs (part probabilities, NPCS, NPCS -> NAOCS scale and translation, joint association and
votes: all canonical, so they pair point by point) for each ``w``; and the refiner's first pass averaged with a second
pass started from it. Every row is scored by `ancsh.evaluation.evaluate_fit`; prints the mean and median rotation
error per part and the mean joint-axis error.
"""

import sys
from dataclasses import replace

import numpy as np
import torch

from ancsh.data.generate import FrameGenerator, GenerationConfig
from ancsh.evaluation import evaluate_fit
from ancsh.learned.inference.provider import LearnedProvider
from ancsh.solvers import Observation, fit

FIELDS = ("seg_prob", "npcs", "scale", "translation", "assoc_prob", "joint")


def average(a, b, w: float):
    """``(1 - w) a + w b`` of two :class:`~ancsh.learned.inference.provider.Prediction` s, field by field."""
    return replace(a, **{f: None if getattr(a, f) is None else (1 - w) * getattr(a, f) + w * getattr(b, f)
                         for f in FIELDS})


def main(category: str, frames: int, weights: list) -> None:
    torch.set_num_threads(1)
    provider = LearnedProvider(category, seed=0, refine="network", refine_passes=1)
    refiner = provider.refiner
    gen = FrameGenerator(GenerationConfig(category=category, split="test", seed=0))
    rows = ["first stage", "refiner (1 pass)"] + [f"average, refiner weight {w:g}" for w in weights] + \
           ["refiner: 1st and 2nd pass averaged"]
    per = {r: [] for r in rows}

    def infer_with(obs, prediction):
        predict = refiner.predict
        refiner.predict = lambda points, input_rotation=None: prediction
        try:
            return refiner.infer(obs)
        finally:
            refiner.predict = predict

    for i in range(frames):
        fr = gen.frame(i)
        obs = Observation(fr.points)
        first = provider.infer(obs)
        base = fit(obs, first.correspondences, "exact_reduced", rng=i)
        if not base.ok:
            continue
        p1 = refiner.predict(obs.points_cam, input_rotation=base.T_cam_npcs[0].rotation.T)
        one = fit(obs, infer_with(obs, p1).correspondences, "exact_reduced", rng=i)
        res = {rows[0]: base, rows[1]: one}
        for w, name in zip(weights, rows[2:-1]):
            res[name] = fit(obs, infer_with(obs, average(first.prediction, p1, w)).correspondences, "exact_reduced", rng=i)
        if one.ok:
            p2 = refiner.predict(obs.points_cam, input_rotation=one.T_cam_npcs[0].rotation.T)
            res[rows[-1]] = fit(obs, infer_with(obs, average(p1, p2, 0.5)).correspondences, "exact_reduced", rng=i)
        for name, r in res.items():
            if r.ok:
                per[name].append(evaluate_fit(r, fr.gt, fr.part_names, fr.joint_names).to_dict())
    print(f"{category}, {frames} frames (`{' '.join(sys.argv)}`)\n")
    print("| row | fits | rotation mean (deg) | rotation median | joint axis (deg) |\n|---|---|---|---|---|")
    for name in rows:
        rot = np.array([[p["rot_deg"] for p in e["parts"]] for e in per[name]], dtype=float)
        axis = np.array([[j["axis_deg"] for j in e["joints"]] for e in per[name]], dtype=float)
        print(f"| {name} | {len(per[name])} | {', '.join(f'{v:.2f}' for v in np.nanmean(rot, 0))} | "
              f"{', '.join(f'{v:.2f}' for v in np.nanmedian(rot, 0))} | {np.nanmean(axis):.2f} |")


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]), [float(w) for w in sys.argv[3].split(",")])
