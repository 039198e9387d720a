"""The learned-cost report: ``learned_cost.md`` / ``.json`` (training frames per CPU-second of each step variant)."""

from __future__ import annotations

import json
from pathlib import Path

from ..report import utc_date, write_text

__all__ = ["write_cost_report"]


def write_cost_report(result: dict, path, *, command: str) -> Path:
    """Write :func:`training_cost` output as Markdown to ``path`` (and the numbers as JSON beside it)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    s = result["settings"]
    date = utc_date()
    lines = [
        "# Training cost of the ANCSH network on a CPU",
        "",
        f"Command: `{command}`  ",
        f"Date: {date}; torch {s['torch']}, {s['machine']}, {s['cpus']} CPUs, load average {s['load_avg']:.1f} at the end  ",
        f"Network: width {s['width']}, {s['num_points']} points, {s['npoints'][0]}/{s['npoints'][1]} centres, "
        f"{s['nsamples'][0]}/{s['nsamples'][1]} neighbours, one backbone (the shipped networks' size); one process, "
        f"{s['repeats']} repetitions per variant interleaved (the first a warm-up), medians.",
        "",
        "Frames per CPU-second = batch / process CPU time of one step (forward, loss, backward, Adam); the machine "
        "is shared, so only ratios measured side by side in one run mean something.",
        "",
        "| Step | batch | threads | step CPU (s) | step wall (s) | frames / CPU-s | frames / wall-s | vs today (CPU) | first loss |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in result["rows"]:
        lines.append(f"| {r['label']} | {r['batch']} | {r['threads']} | {r['step_cpu_s']:.3f} | {r['step_wall_s']:.3f} "
                     f"| {r['frames_per_cpu_s']:.1f} | {r['frames_per_wall_s']:.1f} | {r['speedup_cpu']:.2f}x | {r['first_loss']:.5f} |")
    f = result["forward_ms"]
    lines += [
        "",
        f"Neighbourhood cache: {result['cache_ms_per_frame']:.1f} ms CPU per frame, computed once per frame "
        "(on first load; saved in the run directory), not at every step.",
        "",
        f"Forward pass of one frame ({s['num_points']} points, one thread, eval mode, min CPU time): "
        f"{f['channels_last']:.1f} ms channel-last (sampling and grouping included), {f['reference']:.1f} ms with the reference layers.",
        "",
    ]
    rows = {r["name"]: r for r in result["rows"]}
    for r in result["rows"]:
        if "compile_cpu_s" in r:
            lines += [
                f"Compilation ({r['label']}): the first step took {r['compile_cpu_s']:.0f} s CPU ({r['compile_wall_s']:.0f} s "
                "wall), compilation included; once per process, timed apart from the repetitions. Inductor keeps the "
                "generated kernels on disk (`$TORCHINDUCTOR_CACHE_DIR`, by default `/tmp/torchinductor_<user>`), so a later "
                "process with the same shapes (a resumed run) reuses them. Prediction stays uncompiled (the forward time above).",
                "",
            ]
            if "new" in rows:
                lines += [f"Compiled against uncompiled new step: {rows['new']['step_cpu_s'] / r['step_cpu_s']:.2f}x "
                          "frames per CPU-second.", ""]
    f64 = result["first_loss_float64"]
    lines += [f"First loss of batch {f64['batch']} evaluated in float64 (the same weights and frames): {f64['loss']:.5f}; "
              "the float32 first losses of that batch differ from it by rounding only: "
              + ", ".join(f"{r['name']} {abs(r['first_loss'] - f64['loss']) / abs(f64['loss']):.1e}"
                          for r in result["rows"] if r["batch"] == f64["batch"] and not r["bf16"])
              + " relative.", ""]
    ref = rows.get(result["reference"])
    same = [r for r in result["rows"] if not r["bf16"] and ref is not None and r["batch"] == ref["batch"]]
    if same:
        best = max(same, key=lambda r: r["speedup_cpu"])
        lines += [f"Best variant that computes the same function as today's step: {best['label']}, "
                  f"{best['speedup_cpu']:.2f}x today's frames per CPU-second (issue 12 asks for at least 3x).", ""]
    lines += [
        "Accuracy per training frame: the new step is the same network and computes the same function "
        "(`tests/learned/test_learned_step_cost.py` checks, in float64, that its loss, parameter gradients and "
        "batch-norm running statistics equal the reference step's to 1e-8 relative, and that cached neighbourhoods "
        "equal freshly computed ones index for index); so does the compiled step (the same file checks the network "
        "traced by torch.compile, with dynamo alone and with inductor's C++ kernels; compiled, each set abstraction "
        "max-pools before its last batch norm + ReLU, which are monotone per channel: the same values). The bf16 and batch variants change the numerics or the "
        "optimisation and would need an equal-frames training comparison before use.",
        "",
    ]
    write_text(path, "\n".join(lines))
    write_text(path.with_suffix(".json"), json.dumps(result, indent=1) + "\n")
    return path
