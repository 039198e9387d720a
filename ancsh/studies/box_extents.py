"""Amodal part boxes of learned fits: NPCS extents as measured (``"max"``) or scaled to the NPCS box's unit diagonal
(``"unit_diagonal"``), judged by the paper's 3D IoU (``docs/results/box_extents.md``).

:func:`measure` renders held-out test frames of each category, runs its shipped network once per frame and fits
``exact_reduced`` with each setting of :attr:`ancsh.solvers.fit.FitConfig.box_extents` (the same fit otherwise:
same correspondences and RANSAC seed); :func:`table` writes the mean IoU per part. The command is
``python -m ancsh.cli.bench.box_extents``.
"""

from __future__ import annotations

import numpy as np

__all__ = ["SETTINGS", "measure", "table"]

SETTINGS = ("max", "unit_diagonal")


def measure(categories, frames: int, *, seed: int = 0, progress=None) -> dict:
    """``{category: {"parts": [names], setting: (frames, parts) IoU array, "failed": {setting: count}}}``."""
    from ..data.generate import FrameGenerator, GenerationConfig
    from ..evaluation import evaluate_fit
    from ..learned.inference.provider import LearnedProvider
    from ..learned.network.weights import weights_path
    from ..solvers import fit
    from ..solvers.types import Observation

    out = {}
    for category in categories:
        gen = FrameGenerator(GenerationConfig(category=category, split="test", seed=int(seed)))
        provider = LearnedProvider(str(weights_path(category)), seed=int(seed), num_threads=1)
        rec = {"parts": None, "failed": {s: 0 for s in SETTINGS}, **{s: [] for s in SETTINGS}}
        for i in range(int(frames)):
            fr = gen.frame(i)
            obs = Observation(fr.points)
            corr = provider.correspond(obs)
            rec["parts"] = list(fr.part_names)
            for setting in SETTINGS:
                r = fit(obs, corr, "exact_reduced", config=provider.fit_config(box_extents=setting), rng=int(seed) + i)
                if not r.ok:
                    rec["failed"][setting] += 1
                    continue
                rec[setting].append([p.iou for p in evaluate_fit(r, fr.gt, fr.part_names, fr.joint_names).parts])
        for setting in SETTINGS:
            rec[setting] = np.asarray(rec[setting], dtype=np.float64)
        out[category] = rec
        if progress:
            progress(f"{category}: {frames} frames")
    return out


def table(results: dict) -> list[str]:
    """Markdown rows: per category, the mean 3D IoU (%) per part of each setting and the change."""
    lines = ["| category | parts | IoU, `max` (%) | IoU, `unit_diagonal` (%) | change (points) | failed fits |",
             "|---|---|---|---|---|---|"]
    for category, rec in results.items():
        a, b = (100 * rec[s].mean(axis=0) if rec[s].size else np.full(len(rec["parts"] or []), np.nan) for s in SETTINGS)
        lines.append(f"| {category} | {', '.join(rec['parts'] or [])} | {', '.join(f'{x:.1f}' for x in a)} | "
                     f"{', '.join(f'{x:.1f}' for x in b)} | {', '.join(f'{y - x:+.1f}' for x, y in zip(a, b))} | "
                     f"{rec['failed']['max']} / {rec['failed']['unit_diagonal']} |")
    return lines
