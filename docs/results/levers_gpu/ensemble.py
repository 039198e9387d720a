"""Averaging several trainings' outputs (an ensemble) against its members (docs/results/levers_gpu.md).

    .venv/bin/python docs/results/levers_gpu/ensemble.py FRAMES

The first FRAMES laptop test frames (seed 0, as `ancsh evaluate`), each fitted (exact_reduced) with the
correspondences of every network and of two ensembles whose per-point outputs are the mean of their members'
(runs/levers_gpu/<run>_best.pt of the two GPU calls); prints the mean and median part rotation error per provider.
"""
import sys, time, dataclasses, numpy as np, torch
from ancsh.data.generate import FrameGenerator, GenerationConfig
from ancsh.learned.inference.provider import LearnedProvider
from ancsh.learned.network.weights import load_network
from ancsh.solvers.types import Observation
from ancsh.studies.table1.measure import fit_method
from ancsh.evaluation import evaluate_fit
torch.set_num_threads(1)
class Ens(torch.nn.Module):
    def __init__(s, models): super().__init__(); s.models = torch.nn.ModuleList(models)
    def forward(s, x, nb=None):
        outs = [m(x) for m in s.models]
        return {k: torch.stack([o[k] for o in outs]).mean(0) for k in outs[0]}
def ens(paths):
    nets = [load_network(p) for p in paths]
    return dataclasses.replace(nets[0], model=Ens([n.model for n in nets]).eval(), source="ens")
groups = {g: [f"runs/levers_gpu/{r}_best.pt" for r in rs] for g, rs in
          {"s": ["base_s41", "base_s42", "base_s43"], "f": ["base", "normals", "pose1"]}.items()}
provs = {}
for g, paths in groups.items():
    for p in paths: provs[p.split('/')[-1][:-8]] = LearnedProvider(p, seed=0)
    provs["ens_" + g] = LearnedProvider(ens(paths), seed=0)
N = int(sys.argv[1])
gen = FrameGenerator(GenerationConfig(category="laptop", split="test", seed=0))
res = {k: [] for k in provs}
for i in range(N):
    fr = gen.frame(i); obs = Observation(fr.points)
    for k, pv in provs.items():
        r = fit_method("exact_reduced", obs, pv.correspond(obs), rng=i)
        ev = evaluate_fit(r, fr.gt, fr.part_names, fr.joint_names)
        res[k].append(np.mean([p.rot_deg for p in ev.parts]) if ev.ok else np.nan)
for k, v in res.items():
    v = np.array(v); print(f"{k:12s} mean part rot {np.nanmean(v):.2f}  median {np.nanmedian(v):.2f}  failed {np.isnan(v).sum()}")
