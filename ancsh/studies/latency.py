"""``ancsh bench latency``: how long a prediction takes, warm and cold, per stage, through ``ancsh serve`` and on
several worker processes -- all measured side by side in one run on this machine (``docs/results/latency.md``).

- **Warm** (:func:`measure_warm`): ``predict_depth`` without a mask on the shared real frames and on stress scenes
  (two or three objects of one category, :mod:`ancsh.studies.stress_scenes`), the network loaded once, one torch
  thread; each frame predicted once untimed, then ``repeats`` times, the median kept. With the consensus of
  ``hypotheses`` tries per candidate (the default) and with one try, so the consensus's share is measured.
- **Stages** (:func:`stage_profile`): one profiled prediction per frame, its time split into isolation, the cheap
  segment checks, point sampling, network passes, fits, render-and-compare, the object features and the rest.
  The profiler adds its own overhead: the shares are read from it, the totals from the unprofiled runs.
- **First call** (:func:`first_call`): a fresh provider's first prediction against its second, in total and in the
  network (what a report's first row pays once).
- **Cold** (:func:`measure_cold`): ``ancsh predict`` on one frame in a fresh process (wall clock, after one untimed
  run that compiles the bytecode), beside the interpreter with the CLI alone and with ``import torch``.
- **Serve** (:func:`measure_serve`): sequential ``/predict`` requests of one client to ``ancsh serve`` (in this
  process, its own thread), requests per second, and whether each answer is ``predict_depth``'s.
- **Workers** (:func:`measure_workers`): a folder of frames through :func:`~ancsh.learned.inference.folder.predict_folder`
  in this process, then at 1 and 2 spawned worker processes (their start-up included: like with like), frames per
  second.
"""

from __future__ import annotations

import cProfile
import pstats
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from ..outputs import without_timings
from .report import Provenance, write_json, write_text

__all__ = ["STAGES", "first_call", "latency_frames", "measure_cold", "measure_serve", "measure_warm", "measure_workers",
           "stage_profile", "write_latency_report"]

#: Targets of issue 61, checked in the report.
WARM_TARGET_MS = 100.0
COLD_TARGET_S = 1.5
SERVE_TARGET_RPS = 8.0

#: Stages of a prediction by the functions that do them (file suffix, function name); none runs inside another.
STAGES = {
    "isolation": [("isolate/proposals.py", "isolate_object")],
    "segment checks": [("isolate/verification.py", "out_of_view"), ("isolate/verification.py", "behind_surroundings")],
    "point sampling": [("inference/candidate.py", "depth_to_points")],
    "network": [("inference/provider.py", "predict_points")],
    "fit": [("solvers/fit.py", "fit")],
    "render-and-compare": [("solvers/twin.py", "compare_fit")],
    "object features": [("inference/confidence.py", "object_features")],
}


def latency_frames(stress: int = 4, *, seed: int = 0) -> list:
    """``(name, depth, intrinsics, category)`` of the frames measured: the shared real frames (each with its first
    object's category, the negative frame with the first category seen) and ``stress`` stress scenes of the box
    and the laptop in turn (the kinds of :data:`~ancsh.studies.stress_scenes.KINDS`, sensor noise)."""
    import zlib

    from ..data.generate import FrameGenerator, GenerationConfig
    from ..data.noise import DepthNoise, apply_noise
    from ..data.real_frames import default_real_frame_folders, load_real_frame
    from ..data.scenes import render_scene
    from .stress_scenes import KINDS, PIXEL_SCALE

    frames, first = [], None
    real = [load_real_frame(f) for f in default_real_frame_folders()]
    for fr in real:
        if fr.objects:
            first = first or fr.objects[0].category
    for fr in real:
        category = fr.objects[0].category if fr.objects else first
        if category is not None:
            frames.append((fr.name, fr.depth, fr.intrinsics, category))
    for i in range(int(stress)):
        category = ("box", "laptop")[i % 2]
        kind, companions, translucent = KINDS[i % len(KINDS)]
        gen = FrameGenerator(GenerationConfig(category=category, split="test", seed=seed))
        key = [seed, i, zlib.crc32(category.encode()), 0x1A7]
        scene = render_scene(gen, i, np.random.default_rng(key), companions=companions, translucent=translucent,
                             pixel_scale=PIXEL_SCALE)
        depth = apply_noise(scene.depth, DepthNoise(), np.random.default_rng(key + [1]))
        frames.append((f"stress {category} {kind} #{i}", depth, scene.intrinsics, category))
    return frames


def _providers():
    from ..learned.inference.provider import LearnedProvider

    cache = {}

    def get(category: str):
        if category not in cache:
            cache[category] = LearnedProvider(category, seed=0, refine="auto")
        return cache[category]

    return get


def measure_warm(frames, *, repeats: int = 3, hypotheses=(3, 1), progress=None) -> list[dict]:
    """Per frame and number of hypotheses: the median wall time of ``repeats`` warm predictions (ms), the stage
    timings of the last one (``timings_ms``) and the objects found."""
    from ..learned.inference.predict import predict_depth

    provider = _providers()
    rows = []
    for name, depth, intr, category in frames:
        p = provider(category)
        for h in hypotheses:
            predict_depth(depth, intr, category, provider=p, hypotheses=h)  # warm: programs built, caches filled
            times, pred = [], None
            for _ in range(int(repeats)):
                t0 = time.perf_counter()
                pred = predict_depth(depth, intr, category, provider=p, hypotheses=h)
                times.append(1e3 * (time.perf_counter() - t0))
            rows.append({"frame": name, "category": category, "pixels": int(depth.size), "hypotheses": int(h),
                         "ms": float(np.median(times)), "ms_all": times, "objects": len(pred.objects),
                         "timings_ms": {k: float(v) for k, v in pred.timings_ms.items()}})
            if progress is not None:
                progress(f"warm {name} (hypotheses {h}): {rows[-1]['ms']:.0f} ms")
    return rows


def stage_profile(fn) -> tuple[dict, float]:
    """``({stage: ms}, total ms)`` of one call of ``fn()`` under cProfile (:data:`STAGES`; ``"other"`` the rest)."""
    profiler = cProfile.Profile()
    t0 = time.perf_counter()
    profiler.enable()
    try:
        fn()
    finally:
        profiler.disable()
    total = 1e3 * (time.perf_counter() - t0)
    stats = pstats.Stats(profiler).stats  # {(file, line, name): (cc, nc, tt, ct, callers)}
    out = {}
    for stage, functions in STAGES.items():
        out[stage] = 1e3 * sum(ct for (file, _, name), (_, _, _, ct, _) in stats.items()
                               if any(file.endswith(suffix) and name == fname for suffix, fname in functions))
    out["other"] = max(total - sum(out.values()), 0.0)
    return out, total


def measure_stages(frames, *, progress=None) -> list[dict]:
    """One :func:`stage_profile` of a warm prediction per frame (the default consensus)."""
    from ..learned.inference.predict import predict_depth

    provider = _providers()
    rows = []
    for name, depth, intr, category in frames:
        p = provider(category)
        predict_depth(depth, intr, category, provider=p)
        stages, total = stage_profile(lambda: predict_depth(depth, intr, category, provider=p))
        rows.append({"frame": name, "stages_ms": stages, "profiled_ms": total})
        if progress is not None:
            progress(f"stages {name}: {total:.0f} ms profiled")
    return rows


def first_call(frame) -> dict:
    """A fresh provider's first and second prediction of ``frame`` (total and network ms), and its load time."""
    from ..learned.inference.predict import predict_depth
    from ..learned.inference.provider import LearnedProvider

    name, depth, intr, category = frame
    t0 = time.perf_counter()
    p = LearnedProvider(category, seed=0, refine="auto")
    out = {"frame": name, "load_ms": 1e3 * (time.perf_counter() - t0)}
    for which in ("first", "second"):
        t0 = time.perf_counter()
        pred = predict_depth(depth, intr, category, provider=p, hypotheses=1)
        out[f"{which}_ms"] = 1e3 * (time.perf_counter() - t0)
        out[f"{which}_network_ms"] = float(pred.timings_ms.get("network", float("nan")))
    return out


def _wall(args: list[str], timeout: float = 600.0) -> float:
    """Wall seconds of one run of ``args`` in a fresh process that may cache its bytecode (``PYTHONDONTWRITEBYTECODE``
    left out of its environment: a user's Python writes ``__pycache__``, some sandboxes set it)."""
    import os

    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    t0 = time.perf_counter()
    subprocess.run(args, check=False, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, timeout=timeout, env=env)
    return time.perf_counter() - t0


def measure_cold(folder: Path, category: str, *, repeats: int = 2) -> dict:
    """Wall seconds of a fresh ``ancsh predict`` on ``folder``'s ``depth.png`` / ``K.json`` (the median of
    ``repeats``, after one untimed run: the bytecode compiled and the files in the disk cache, as for a user's
    second command), of ``ancsh --version`` and of ``python -c "import torch"``."""
    py = sys.executable
    predict = [py, "-m", "ancsh", "predict", "--depth", str(folder / "depth.png"), "--intrinsics", str(folder / "K.json"),
               "--category", category]
    _wall(predict)
    return {"frame": folder.name, "category": category,
            "cli_s": float(np.median([_wall([py, "-m", "ancsh", "--version"]) for _ in range(repeats)])),
            "torch_s": float(np.median([_wall([py, "-c", "import torch"]) for _ in range(repeats)])),
            "predict_s": float(np.median([_wall(predict) for _ in range(repeats)]))}


def measure_serve(frame, *, requests: int = 8) -> dict:
    """Sequential requests of ``frame`` to a service in this process: requests per second (the first untimed)
    and whether every answer is ``predict_depth``'s (timings aside)."""
    import threading

    from ..learned.inference.predict import predict_depth
    from ..service import PredictionService, ServiceClient, make_server

    name, depth, intr, category = frame
    server = make_server(PredictionService(categories=[category]), "127.0.0.1", 0)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        client = ServiceClient(server.url)
        first = client.predict(depth, intr, category)
        t0 = time.perf_counter()
        answers = [client.predict(depth, intr, category) for _ in range(int(requests))]
        seconds = time.perf_counter() - t0
    finally:
        server.shutdown()
        server.server_close()
    direct = without_timings(predict_depth(depth, intr, category).to_json(), drop=("input",))
    same = all(without_timings(a, drop=("input",)) == direct for a in [first] + answers)
    return {"frame": name, "requests": int(requests), "seconds": seconds, "rps": requests / seconds,
            "same_as_predict": bool(same)}


def measure_workers(frames, *, copies: int = 2, workers=(1, 2)) -> list[dict]:
    """Frames per second of a folder (every frame of one category, ``copies`` times): in this process (the models
    loaded here, nothing imported), then in each number of ``workers`` spawned processes (each imports the package
    and loads the models once: like with like, their start-up included)."""
    from ..executors import LocalExecutor
    from ..learned.inference.folder import FolderOptions, predict_folder

    if not frames:
        return []
    category, intr = frames[0][3], frames[0][2]
    same = [f for f in frames if f[3] == category and f[2] == intr]
    rows = []
    with tempfile.TemporaryDirectory(prefix="ancsh-latency-") as tmp:
        folder = Path(tmp) / "frames"
        folder.mkdir()
        files = []
        for c in range(int(copies)):
            for i, (_, depth, _, _) in enumerate(same):
                path = folder / f"f{c}_{i}.npy"
                np.save(path, depth)
                files.append(path)
        options = FolderOptions(category=category, intrinsics=intr, provider={"seed": 0, "refine": "auto",
                                                                              "num_threads": 1})
        for n, where in [(1, "this process")] + [(int(n), "spawned") for n in workers]:
            out = Path(tmp) / f"out{n}{where[0]}"
            out.mkdir()
            t0 = time.perf_counter()
            predict_folder(files, options, out, executor=LocalExecutor(workers=n, in_process=where == "this process"))
            seconds = time.perf_counter() - t0
            rows.append({"workers": n, "where": where, "frames": len(files), "seconds": seconds,
                         "fps": len(files) / seconds})
    return rows


def write_latency_report(results: dict, path, provenance: Provenance) -> Path:
    """``latency.md`` (and the records as ``latency.json`` beside it)."""
    path = Path(path)
    warm, stages = results["warm"], results["stages"]
    lines = ["# Latency: a prediction warm and cold, per stage, through the service and on workers", "",
             f"Command: `{provenance.command}`  ", f"Date: {provenance.date}; machine: {provenance.machine_text}  ",
             "Study: `ancsh.studies.latency`", "", __doc__.split("\n\n", 1)[1].strip(), ""]
    hyps = sorted({r["hypotheses"] for r in warm}, reverse=True)
    full = [r["ms"] for r in warm if r["hypotheses"] == hyps[0]]
    one = [r["ms"] for r in warm if r["hypotheses"] == hyps[-1]]
    cold, serve = results.get("cold"), results.get("serve")
    lines += ["## Targets (issue 61)", "", "| measure | value | target | met |", "|---|---|---|---|",
              f"| warm median per frame, no mask, consensus of {hyps[0]} (ms) | {np.median(full):.0f} | "
              f"<= {WARM_TARGET_MS:.0f} | {'yes' if np.median(full) <= WARM_TARGET_MS else 'no'} |"]
    if cold is not None:
        lines.append(f"| cold `ancsh predict`, one frame (s wall) | {cold['predict_s']:.2f} | <= {COLD_TARGET_S} | "
                     f"{'yes' if cold['predict_s'] <= COLD_TARGET_S else 'no'} |")
    if serve is not None:
        lines.append(f"| `ancsh serve`, one client (requests/s) | {serve['rps']:.2f} | >= {SERVE_TARGET_RPS:.0f} | "
                     f"{'yes' if serve['rps'] >= SERVE_TARGET_RPS else 'no'} |")
    if len(hyps) > 1:
        lines += ["", f"The consensus ({hyps[0]} hypotheses per candidate against {hyps[-1]}) costs "
                      f"{np.median(full) / np.median(one):.2f}x the time (median over frames): "
                      f"{100 * (1 - np.median(one) / np.median(full)):.0f} % of the warm time."]
    lines += ["", "## Warm, per frame (ms, median of the repeats)", "",
              "| frame | category | pixels | " + " | ".join(f"{h} hypothes{'is' if h == 1 else 'es'}" for h in hyps)
              + " | objects found |",
              "|---|---|---|" + "---|" * len(hyps) + "---|"]
    for name in dict.fromkeys(r["frame"] for r in warm):
        rs = {r["hypotheses"]: r for r in warm if r["frame"] == name}
        r0 = rs[hyps[0]]
        lines.append(f"| {name} | {r0['category']} | {r0['pixels']} | " + " | ".join(f"{rs[h]['ms']:.0f}" for h in hyps)
                     + f" | {r0['objects']} |")
    names = list(STAGES) + ["other"]
    lines += ["", "## Stages (share of one profiled warm prediction, default consensus)", "",
              "| frame | profiled ms | " + " | ".join(names) + " |", "|---|---|" + "---|" * len(names)]
    for r in stages:
        lines.append(f"| {r['frame']} | {r['profiled_ms']:.0f} | "
                     + " | ".join(f"{100 * r['stages_ms'][s] / r['profiled_ms']:.0f} %" for s in names) + " |")
    if stages:
        tot = sum(r["profiled_ms"] for r in stages)
        lines.append("| **all** | " + f"{tot:.0f} | " + " | ".join(
            f"**{100 * sum(r['stages_ms'][s] for r in stages) / tot:.0f} %**" for s in names) + " |")
    fc = results.get("first_call")
    if fc is not None:
        lines += ["", "## The first prediction in a process", "",
                  f"A fresh provider on {fc['frame']} (the first measurement of this run): loading {fc['load_ms']:.0f} ms; "
                  f"the first prediction {fc['first_ms']:.0f} ms (network {fc['first_network_ms']:.0f} ms), the second "
                  f"{fc['second_ms']:.0f} ms (network {fc['second_network_ms']:.0f} ms). What the first pays beyond the "
                  "second is one-time set-up (programs built, templates and calibrations read, torch's first kernels); "
                  "a report's first row carries it, `ancsh serve` and folder prediction pay it once."]
    if cold is not None:
        lines += ["", "## Cold start (s wall, fresh processes)", "", "| `ancsh --version` | `import torch` | "
                  "`ancsh predict` one frame |", "|---|---|---|",
                  f"| {cold['cli_s']:.2f} | {cold['torch_s']:.2f} | {cold['predict_s']:.2f} |"]
    if serve is not None:
        lines += ["", "## Serve", "", f"{serve['requests']} sequential requests of {serve['frame']}: "
                  f"{serve['rps']:.2f} requests/s; every answer {'is' if serve['same_as_predict'] else 'is NOT'} "
                  "`predict_depth`'s (timings aside)."]
    if results.get("workers"):
        rows = results["workers"]
        lines += ["", "## Workers (a folder, start-up included)", "",
                  "`ancsh predict --depth DIR --workers N`: in this process (the models loaded here before the clock "
                  "starts), then in N spawned processes, each importing the package and loading the models once.", "",
                  "| workers | where | frames | s | frames/s |", "|---|---|---|---|---|"]
        lines += [f"| {r['workers']} | {r.get('where', '-')} | {r['frames']} | {r['seconds']:.1f} | {r['fps']:.2f} |"
                  for r in rows]
        spawned = {r["workers"]: r["fps"] for r in rows if r.get("where") == "spawned"}
        if 1 in spawned and 2 in spawned:
            lines += ["", f"2 spawned workers against 1: {spawned[2] / spawned[1]:.2f}x the frames per second."]
    write_text(path, "\n".join(lines) + "\n")
    write_json(path.with_suffix(".json"), {"command": provenance.command, "date": provenance.date,
                                           "machine": provenance.machine, **results}, indent=1)
    return path
