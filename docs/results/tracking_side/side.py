"""Laptop tracking speed: the shipped network (input normals) against the previous one, interleaved frame by frame in
one process, so that machine load falls on both alike (the sequences, tracker settings and timing of
`ancsh bench tracking --sequences 10`: one torch thread, the network every 3rd tracked frame).

    git show e9ec973:ancsh/weights/laptop.pt > /tmp/laptop_previous.pt
    .venv/bin/python docs/results/tracking_side/side.py /tmp/laptop_previous.pt 10 OUT.json

Writes the frames/s and median milliseconds of each network's tracking and per-frame fitting, their ratios, the
command and the machine's load.
"""
import json, os, sys, time
from datetime import datetime, timezone

import numpy as np
from ancsh.studies.tracking.measure import BenchConfig, _sequence_frames
from ancsh.data.generate import FrameGenerator, GenerationConfig
from ancsh.data.sequences import SequenceMotion
from ancsh.learned.inference.provider import LearnedProvider
from ancsh.solvers.types import Observation
from ancsh.tracking.tracker import CategoryTracker, TrackerConfig, fit_frame

previous, n_seq, out_path = sys.argv[1], int(sys.argv[2]), sys.argv[3]
cfg = BenchConfig(categories=("laptop",), providers=("learned",), sequences=n_seq, urdf=None)
tcfg = TrackerConfig(network_every=cfg.network_every, **cfg.tracker)
nets = {"shipped": "ancsh/weights/laptop.pt", "previous": previous}
providers = {k: LearnedProvider(v, num_threads=1) for k, v in nets.items()}
gen = FrameGenerator(GenerationConfig(category="laptop", split="test", seed=cfg.seed, sequence=SequenceMotion(length=cfg.length)))
times = {(k, m): [] for k in nets for m in ("tracking", "per_frame")}
for seq in range(n_seq):
    frames = _sequence_frames(gen, seq, cfg.length, cfg.gap)
    trackers = {k: CategoryTracker(p, tcfg, category="laptop", rng=cfg.seed) for k, p in providers.items()}
    for fr, blank in frames:
        obs = Observation(np.zeros((0, 3)) if blank else fr.points)
        order = list(nets) if fr.time_index % 2 == 0 else list(nets)[::-1]
        for k in order:
            t0 = time.perf_counter(); trackers[k].step(obs); times[(k, "tracking")].append(time.perf_counter() - t0)
            t0 = time.perf_counter(); fit_frame(providers[k], obs, tcfg, "laptop", cfg.seed); times[(k, "per_frame")].append(time.perf_counter() - t0)
    print(f"sequence {seq} done", flush=True)
out = {f"{k}/{m}": {"frames_per_s": len(v) / sum(v), "median_ms": 1e3 * float(np.median(v))} for (k, m), v in times.items()}
for key in ("tracking", "per_frame"):
    out[f"shipped / previous {key} frames/s"] = out[f"shipped/{key}"]["frames_per_s"] / out[f"previous/{key}"]["frames_per_s"]
out["command"] = "python " + " ".join(sys.argv)
out["date"] = datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
out["load_average_1_5_15"] = os.getloadavg()
out["cpus"] = os.cpu_count()
with open(out_path, "w") as f:
    json.dump(out, f, indent=1)
print(json.dumps(out, indent=1))
