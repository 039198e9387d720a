"""``ancsh bench scaling``: frames/s of data generation and of evaluation on 1 and 2 workers, local
processes against Ray, and the CPU cost per frame that sizes a cluster.

Both jobs run their real work units through :mod:`ancsh.executors`: ``ancsh data generate``'s
frame worker (tasks of ``chunk`` frames at 640x480, 1024 points, Kinect noise) and ``ancsh
evaluate``'s frame evaluator (one held-out frame per task: render, network, every fitting method).
Each configuration is timed from the call to its last result, start-up included (worker processes
or Ray actors, imports, models); the rate *after the first result* leaves the start-up out. The
configurations run interleaved, ``rounds`` times each (the order reversed every other round), and
the table reports medians, so a machine shared with other jobs loads them alike. The CPU cost per
frame is the process CPU time of the in-process run after its first result: what one free core
spends, the figure that sizes a cluster.
"""

from __future__ import annotations

import math
import os
import statistics
import time
from dataclasses import dataclass, field

__all__ = ["Run", "ScalingResult", "measure_scaling", "scaling_report"]


@dataclass(frozen=True)
class Run:
    """One timed configuration of one job.

    Attributes
    ----------
    job : str
        ``"generate"`` or ``"evaluate"``.
    executor : str
        ``"in-process"`` (the tasks in the benchmark's own process: the CPU cost per frame), ``"local"``
        (spawned processes) or ``"ray"``.
    workers : int
    frames : int
    wall_s : float
        From the call to the last result (worker start-up included).
    first_s : float
        From the call to the first result.
    first_frames : int
        Frames in the first result.
    cpu_s : float or None
        This process's CPU time after the first result (in-process runs only, else ``None``).
    """

    job: str
    executor: str
    workers: int
    frames: int
    wall_s: float
    first_s: float
    first_frames: int
    cpu_s: float | None = None

    @property
    def frames_per_s(self) -> float:
        return self.frames / self.wall_s

    @property
    def steady_frames_per_s(self) -> float:
        """Frames per second after the first result (start-up left out); NaN with a single result."""
        if self.frames == self.first_frames:
            return float("nan")
        return (self.frames - self.first_frames) / max(self.wall_s - self.first_s, 1e-9)


@dataclass(frozen=True)
class ScalingResult:
    """Every :class:`Run` of :func:`measure_scaling`, the Ray start-up time and the machine's load."""

    runs: tuple
    ray_start_s: float | None
    load_before: tuple
    load_after: tuple
    cpu_count: int
    settings: dict = field(default_factory=dict)

    def median(self, job: str, executor: str, workers: int, attribute: str) -> float:
        values = [getattr(r, attribute) for r in self.runs if (r.job, r.executor, r.workers) == (job, executor, workers)]
        return statistics.median(values) if values else float("nan")

    def cpu_per_frame(self, job: str) -> float:
        """Median CPU seconds per frame of the in-process runs (after their first result)."""
        values = [r.cpu_s / (r.frames - r.first_frames) for r in self.runs
                  if r.job == job and r.cpu_s is not None and r.frames > r.first_frames]
        return statistics.median(values) if values else float("nan")


def _timed(executor, make_worker, args, tasks, frames_of, job, in_process: bool) -> Run:
    t0 = time.perf_counter()
    first_s = first_frames = None
    frames = 0
    c0 = None
    for result in executor.imap(make_worker, args, tasks):
        n = frames_of(result)
        frames += n
        if first_s is None:
            first_s, first_frames = time.perf_counter() - t0, n
            c0 = time.process_time()
    wall = time.perf_counter() - t0
    kind = "in-process" if in_process else executor.kind
    return Run(job, kind, executor.workers, frames, wall, first_s, first_frames,
               time.process_time() - c0 if in_process else None)


def measure_scaling(*, gen_frames: int = 64, chunk: int = 8, eval_frames: int = 8, rounds: int = 2,
                    workers=(1, 2), executors=("local", "ray"), category: str = "laptop", progress=print) -> ScalingResult:
    """Time generation and evaluation on every executor and worker count (see the module docstring)."""
    from ..data.generate import GenerationConfig, _FrameWorker
    from ..executors import LocalExecutor, import_ray, make_executor, start_ray
    from .table1.measure import DEFAULT_METHODS, _FrameEvaluator
    from ..learned.network.weights import weights_path

    if "ray" in executors:
        import_ray()  # a clear error before any measurement
    gen_config = GenerationConfig(category=category, split="train", seed=0)
    gen_tasks = [list(range(i, min(i + chunk, gen_frames))) for i in range(0, gen_frames, chunk)]
    methods = (*DEFAULT_METHODS, "template")  # the refinement network needs weights not every category ships
    eval_args = (category, 0, None, str(weights_path(category)), None, 1, methods, "cpu")
    configs = [("in-process", 1)] + [(kind, n) for kind in executors for n in workers]
    load_before = os.getloadavg()
    runs = []
    ray_start = None
    ray = None
    if "ray" in executors:
        ray = import_ray()
        t0 = time.perf_counter()
        if not start_ray(ray, address=None, num_cpus=max(workers)):
            raise ValueError("executors: Ray is already running in this process; measure on a fresh local Ray")
        ray_start = time.perf_counter() - t0
        progress(f"local Ray started in {ray_start:.1f} s")
    try:
        for r in range(rounds):
            order = configs if r % 2 == 0 else configs[::-1]
            for kind, n in order:
                in_process = kind == "in-process"
                executor = LocalExecutor(1) if in_process else (
                    LocalExecutor(n, in_process=False) if kind == "local" else make_executor(kind, n))
                for job, make, args, tasks, count in (
                    ("generate", _FrameWorker, (gen_config,), gen_tasks, len),
                    ("evaluate", _FrameEvaluator, eval_args, list(range(eval_frames)), lambda _: 1),
                ):
                    run = _timed(executor, make, args, tasks, count, job, in_process)
                    runs.append(run)
                    progress(f"round {r + 1}/{rounds} {job:8s} {kind:5s} x{n}: {run.wall_s:6.1f} s, first result "
                             f"{run.first_s:5.1f} s, {run.steady_frames_per_s:6.2f} frames/s after it")
    finally:
        if ray is not None:
            ray.shutdown()
    settings = dict(gen_frames=gen_frames, chunk=chunk, eval_frames=eval_frames, rounds=rounds, workers=list(workers),
                    executors=list(executors), category=category)
    return ScalingResult(tuple(runs), ray_start, tuple(load_before), tuple(os.getloadavg()), os.cpu_count(), settings)


def _cores(frames: float, cpu_per_frame: float, hours: float) -> str:
    return f"{math.ceil(frames * cpu_per_frame / (hours * 3600.0)):,}"


def scaling_report(result: ScalingResult, *, command: str) -> str:
    """The Markdown report of a :func:`measure_scaling` result (computes nothing but medians and ratios)."""
    s = result.settings
    lines = [
        "# Scaling: data generation and evaluation on local processes and on Ray",
        "",
        f"Generated {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())} by `{command}`.",
        "",
        f"Machine: {result.cpu_count} CPU cores; 1/5/15-min load average "
        f"{' / '.join(f'{v:.1f}' for v in result.load_before)} before and "
        f"{' / '.join(f'{v:.1f}' for v in result.load_after)} after (other jobs share the cores: read the ratios, "
        "which the interleaved runs share, rather than the absolute rates).",
        "",
        f"Jobs: `generate` = {s['gen_frames']} frames of `{s['category']}` (640x480, 1024 points, Kinect noise) in tasks "
        f"of {s['chunk']} frames, the work of `ancsh data generate`; `evaluate` = {s['eval_frames']} held-out "
        f"`{s['category']}` frames, one per task: render, network, all five fitting methods, the work of `ancsh evaluate`. "
        f"Each configuration ran {s['rounds']} times, interleaved with the others (order reversed every other round); "
        "medians. *local* = spawned worker processes (`--workers N`), *ray* = Ray actors on a local Ray, "
        "*in-process* = the tasks in the benchmark's own process (what `--workers 1` does; after the first round its "
        "imports and caches are warm, so only its rate after the first result compares). *Wall* includes starting "
        "the workers (processes or Ray actors, imports, models); *after the first result* leaves that start-up out."
        + (f" Starting the local Ray itself took {result.ray_start_s:.1f} s (once per command, not in the table)."
           if result.ray_start_s is not None else ""),
        "",
        "| job | executor | workers | wall (s) | first result (s) | frames/s (wall) | frames/s after the first result "
        "| speed-up after the first result (vs 1 local process) | Ray / local wall |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for job in ("generate", "evaluate"):
        base = result.median(job, "local", 1, "steady_frames_per_s")
        for kind, n in [("in-process", 1)] + [(k, n) for k in s["executors"] for n in s["workers"]]:
            wall = result.median(job, kind, n, "wall_s")
            steady = result.median(job, kind, n, "steady_frames_per_s")
            local_wall = result.median(job, "local", n, "wall_s")
            ratio = f"{wall / local_wall:.2f}" if kind == "ray" else "-"
            lines.append(
                f"| {job} | {kind} | {n} | {wall:.1f} | {result.median(job, kind, n, 'first_s'):.1f} | "
                f"{result.median(job, kind, n, 'frames_per_s'):.2f} | {steady:.2f} | {steady / base:.2f}x | {ratio} |")
    gen_cpu, eval_cpu = result.cpu_per_frame("generate"), result.cpu_per_frame("evaluate")
    lines += [
        "",
        "## Sizing: cores for N frames in T hours",
        "",
        f"CPU cost per frame, measured in the benchmark's process after its first result: generation {gen_cpu:.3f} CPU-s, "
        f"evaluation {eval_cpu:.3f} CPU-s (render, network and five fits). Frames are independent tasks, so "
        "the cores a job needs are N x cost / T, plus each worker's start-up (the first-result column: seconds, "
        "once per worker) and whatever share of the cores other jobs take; Ray adds its start-up once per command "
        "and the per-task overhead measured above.",
        "",
        "| frames N | generation, 1 h | 8 h | 24 h | evaluation, 1 h | 8 h | 24 h |",
        "|---|---|---|---|---|---|---|",
    ]
    for n in (1e4, 1e5, 1e6, 1e7):
        lines.append(f"| {int(n):,} | " + " | ".join(_cores(n, gen_cpu, h) for h in (1, 8, 24)) + " | "
                     + " | ".join(_cores(n, eval_cpu, h) for h in (1, 8, 24)) + " |")
    lines += ["", "## Every run", "", "| job | executor | workers | wall (s) | first result (s) | frames | CPU s after the first result |",
              "|---|---|---|---|---|---|---|"]
    for r in result.runs:
        lines.append(f"| {r.job} | {r.executor} | {r.workers} | {r.wall_s:.2f} | {r.first_s:.2f} | {r.frames} | "
                     f"{'-' if r.cpu_s is None else f'{r.cpu_s:.2f}'} |")
    return "\n".join(lines) + "\n"


DEFAULTS = dict(gen_frames=64, chunk=8, eval_frames=8, rounds=2, workers="1,2", executors="local,ray", out=None)
"""The options' defaults (left out of the command line quoted in the report)."""


