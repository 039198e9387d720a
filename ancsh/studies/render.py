"""``ancsh bench render``: rendering throughput per category -- raw ray casting, with visibility, full frames.

:func:`measure_render` times, in one process, the ray casting of rendered views (without and with the visibility
pass) and the whole frame (render + noise + points + ground truth) of each category, and emits the table rows as it
goes; :func:`write_render_report` writes them with the command, the date, the machine and the verdict against
:data:`RENDER_TARGET_FPS`. The arguments are in :mod:`ancsh.cli.bench.render`.
"""

from __future__ import annotations

import os
import platform
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from .report import Provenance, write_text

__all__ = ["RENDER_TARGET_FPS", "measure_render", "render_target_verdict", "write_render_report"]

RENDER_TARGET_FPS = 50.0


def render_target_verdict(full_fps: dict, width: int, height: int) -> str:
    """The render target (>= 50 full frames/s at 640x480 per category) against what was measured here.

    ``full_fps`` maps a category to its measured full-frame rate (frames/s) at ``width x height`` pixels.
    """
    target = f"Target: >= {RENDER_TARGET_FPS:.0f} full frames/s for 640x480 frames of each category"
    if (width, height) != (640, 480):
        return f"{target}; not checked (this run measured {width}x{height} frames)."
    met = [c for c, fps in full_fps.items() if fps >= RENDER_TARGET_FPS]
    return f"{target}; met here by {len(met)} of {len(full_fps)} categories" + (
        f" ({', '.join(met)})." if met and len(met) < len(full_fps) else ".")


def measure_render(categories, intrinsics, *, frames: int, threads: int, seed: int,
                   emit: Callable[[str], None]) -> tuple[list[str], dict[str, float]]:
    """Time rendering per category; returns ``(table lines, {category: full frames/s})``.

    Parameters
    ----------
    categories : sequence of str
        Procedural categories (test instances).
    intrinsics : ancsh.data.render.Intrinsics
        The camera of every frame (its size sets the cost).
    frames, threads, seed : int
        Frames per category and mode, open3d ray-casting threads, seed of the states and viewpoints.
    emit : callable
        Receives each table line as soon as it is measured (the command prints it).
    """
    from ..data.generate import FrameGenerator, FrameRejected, GenerationConfig
    from ..data.render import sample_viewpoint, viewpoint_range

    intr = intrinsics
    lines = []

    def say(line: str) -> None:
        emit(line)
        lines.append(line)

    say(
        f"ancsh bench render: {intr.width}x{intr.height}, {frames} frames per category, "
        f"{threads} ray-casting thread(s), one process; {platform.machine()}, {os.cpu_count()} CPUs, "
        f"load average {os.getloadavg()[0]:.1f}"
    )
    say("fr/s = wall-clock frames per second; CPU ms = process CPU time per frame (what a free core would take)")
    full_fps: dict[str, float] = {}
    header = ("category", "raycast fr/s", "CPU ms", "+visib. fr/s", "CPU ms", "full fr/s", "CPU ms", "obj. pixels")
    say(f"{header[0]:16s}" + "".join(f"{h:>13s}" for h in header[1:]))
    for cat in categories:
        gen = FrameGenerator(GenerationConfig(category=cat, split="test", seed=seed, intrinsics=intr))
        rng = np.random.default_rng(seed)
        jobs = []
        for i in range(frames):
            model, renderer = gen.instance(i % gen.num_instances)
            q = model.random_states(rng)
            jobs.append((renderer, q, sample_viewpoint(viewpoint_range(cat), rng, model, q)))
        for i in range(gen.num_instances):  # load every instance before timing
            gen.instance(i)
        jobs[0][0].render(jobs[0][1], jobs[0][2], intr, nthreads=threads)  # warm-up (open3d start-up)
        cols, pixels = [], 0
        for vis in (False, True):
            t0, c0 = time.perf_counter(), time.process_time()
            for renderer, q, T in jobs:
                view = renderer.render(q, T, intr, visibility=vis, nthreads=threads)
                pixels += int((view.part_ids >= 0).sum()) if not vis else 0
            cols += [frames / (time.perf_counter() - t0), 1e3 * (time.process_time() - c0) / frames]
        t0, c0 = time.perf_counter(), time.process_time()
        try:
            for i in range(frames):
                gen.frame(i)
        except FrameRejected as exc:
            raise ValueError(f"--width, --height: no usable frame at {intr.width}x{intr.height} pixels ({exc}); "
                             "use a larger image") from None
        cols += [frames / (time.perf_counter() - t0), 1e3 * (time.process_time() - c0) / frames]
        say(f"{cat:16s}" + "".join(f"{x:13.1f}" for x in cols) + f"{pixels // frames:13d}")
        full_fps[cat] = cols[4]
    return lines, full_fps


def write_render_report(path, lines: list[str], full_fps: dict, width: int, height: int, *,
                        provenance: Provenance) -> Path:
    """The table of :func:`measure_render` as markdown, with its command, date, machine and target verdict."""
    return write_text(path, (
        "# Rendering throughput\n\n"
        f"Generated {provenance.date} by `{provenance.command}`.\n"
        f"Measured on {provenance.machine_text}. {render_target_verdict(full_fps, width, height)}\n\n"
        "```\n" + "\n".join(lines) + "\n```\n"
    ))
