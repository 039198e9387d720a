"""``ancsh bench fit-profile``: where one exact fit spends its time, stage by stage, per category
(``docs/results/fit_profile.md``).

The frames are ``ancsh bench fit``'s (:func:`ancsh.studies.fit.load_frames`, the same seeds, one corruption level,
default ``realistic``: the corrupted correspondences and the RANSAC seeds of its frame ``f`` are the benchmark's).
Each method (``formulation/backend``, default the default exact fit ``exact_reduced/lm``, the projected
Levenberg-Marquardt, and ``exact_reduced/ipopt``, the default before it) fits every frame ``repeats`` times, each call timed around it (the
median kept: the ``total`` column) and inside :func:`ancsh.solvers.stages.record_stages` (a clock read per stage,
about a microsecond a fit), which splits it into the driver's stages (:data:`~ancsh.solvers.stages.FIT_STAGES`: RANSAC, program lookup, moments, the
solve, covariance, result, ...) and the solve into the backend's own parts
(:data:`~ancsh.solvers.stages.SOLVER_STAGES`: IPOPT's CasADi evaluations of the objective, gradient and Hessian from
its statistics and the rest of its call -- its linear solves, line search and bookkeeping; the LM's CasADi
evaluations, its numpy normal equations and its Python loop); a stage's figure is its median over the calls of a
frame, so the stages need not add up to the total exactly. Before timing every method fits each category's first
frame once (programs built), as the benchmark does. With ``official`` (default) the official ANCSH scheme fits each
frame once beside them, so the page can say what time per fit a 1000x speed-up would need on this machine.
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass

import numpy as np

from ..geometry._checks import check_bool, check_int
from .report import Provenance, write_json, write_text

__all__ = ["DEFAULT_METHODS", "ProfileConfig", "profile_fits", "write_profile_report"]

DEFAULT_METHODS = ("exact_reduced/lm", "exact_reduced/ipopt")
#: The speed-up the profile measures against (issue 63: the official scheme's mean over the exact fit's).
TARGET_SPEEDUP = 1000.0


@dataclass(frozen=True)
class ProfileConfig:
    """What :func:`profile_fits` runs.

    Attributes
    ----------
    categories : tuple of str
        Procedural categories (``()`` = all eight, in :data:`~ancsh.data.procedural.CATEGORIES` order).
    frames_per_category : int
    level : str
        One corruption preset of :data:`~ancsh.solvers.providers.oracle.CORRUPTION_PRESETS`.
    methods : tuple of str
        ``formulation/backend`` pairs of :data:`~ancsh.solvers.fit.FORMULATIONS`, default config.
    repeats : int
        Timed (and recorded) calls per frame and method (their median is the frame's time).
    official : bool
        Also time the official scheme once per frame.
    seed : int
        ``ancsh bench fit``'s seed.
    """

    categories: tuple = ()
    frames_per_category: int = 20
    level: str = "realistic"
    methods: tuple = DEFAULT_METHODS
    repeats: int = 3
    official: bool = True
    seed: int = 0

    def __post_init__(self):
        from ..solvers.fit import FORMULATIONS
        from ..solvers.providers.oracle import CORRUPTION_PRESETS

        check_int(self.frames_per_category, "frames_per_category", minimum=1)
        check_int(self.repeats, "repeats", minimum=1)
        check_int(self.seed, "seed", minimum=0)
        check_bool(self.official, "official")
        if self.level not in CORRUPTION_PRESETS:
            raise ValueError(f"level: expected one of {list(CORRUPTION_PRESETS)}, got {self.level!r}")
        object.__setattr__(self, "categories", tuple(self.categories))
        object.__setattr__(self, "methods", tuple(self.methods))
        if not self.methods:
            raise ValueError("methods: expected at least one formulation/backend")
        for m in self.methods:
            name, _, solver = m.partition("/")
            if name not in FORMULATIONS or solver not in FORMULATIONS[name].solvers:
                known = [f"{n}/{s}" for n, f in FORMULATIONS.items() for s in f.solvers]
                raise ValueError(f"methods: unknown {m!r}; known: {known}")


def profile_fits(config: ProfileConfig, progress=None) -> dict:
    """Profile every method of ``config`` on the benchmark's frames.

    Returns
    -------
    dict
        ``{"config", "categories", "stages", "solver_stages", "rows"}``: one row per (category, method) with
        ``frames``, ``ok`` (fraction), ``total_ms`` (mean over frames of the median call; ``total_median_ms`` their
        median), ``stages_ms`` / ``solver_ms`` (per frame the median over its calls, averaged over frames;
        milliseconds, solver ``*.iterations`` counts) and, with ``official``, ``official_ms`` (its mean) and
        ``ratio`` (official mean / total mean).
    """
    from ..data.procedural import CATEGORIES
    from ..solvers.fit import fit
    from ..solvers.providers.oracle import corrupt_ground_truth
    from ..solvers.stages import FIT_STAGES, SOLVER_STAGES, record_stages
    from ..solvers.types import Observation
    from .fit import BenchConfig, load_frames

    cats = config.categories or tuple(CATEGORIES)
    frames = load_frames(BenchConfig(categories=cats, frames_per_category=config.frames_per_category,
                                     levels=(config.level,), seed=config.seed))
    methods = [tuple(m.split("/")) for m in config.methods]
    official = None
    if config.official:
        from ..solvers.official import OfficialSettings, fit_official

        settings = OfficialSettings()
        official = lambda obs, corr, rng: fit_official(obs, corr, settings=settings, rng=rng)  # noqa: E731
    acc: dict = {}
    warmed = set()
    for f_i, frame in enumerate(frames):  # f_i over all categories, as in run_benchmark
        obs = Observation(frame.points)
        if frame.category not in warmed:
            warmed.add(frame.category)
            clean = corrupt_ground_truth(frame.gt, frame.points, "none", 0, joint_limits=frame.joint_limits)
            for form, solver in methods:
                fit(obs, clean.correspondences, form, solver, rng=np.random.default_rng(0))
        seed = [config.seed, f_i, 0]
        corr = corrupt_ground_truth(frame.gt, frame.points, config.level, np.random.default_rng(seed),
                                    joint_limits=frame.joint_limits).correspondences
        line = []
        for form, solver in methods:
            calls = []
            for _ in range(config.repeats):
                with record_stages() as times:
                    t0 = time.perf_counter()
                    result = fit(obs, corr, form, solver, rng=np.random.default_rng(seed + [7]))
                    calls.append((time.perf_counter() - t0, result.ok, times))
            acc.setdefault((frame.category, f"{form}/{solver}"), _Acc()).add_calls(calls)
            line.append(f"{form}/{solver} {1e3 * np.median([c[0] for c in calls]):.2f} ms")
        if official is not None:
            t0 = time.perf_counter()
            official(obs, corr, np.random.default_rng(seed + [7]))
            acc.setdefault((frame.category, "official"), _Acc()).add_calls([(time.perf_counter() - t0, True, None)])
            line.append(f"official {1e3 * (time.perf_counter() - t0):.0f} ms")
        if progress is not None:
            progress(f"{frame.category} #{frame.index}: " + ", ".join(line))
    rows = []
    for cat in cats:
        ref = acc.get((cat, "official"))
        for m in config.methods:
            a = acc.get((cat, m))
            if a is None:
                continue
            row = a.row(cat, m)
            if ref is not None:
                row["official_ms"] = 1e3 * float(np.mean(ref.total))
                row["ratio"] = row["official_ms"] / row["total_ms"]
            rows.append(row)
    return {"config": asdict(config), "categories": list(cats), "stages": dict(FIT_STAGES),
            "solver_stages": dict(SOLVER_STAGES), "rows": rows}


class _Acc:
    """Per (category, method): each frame's median call time and its stages' medians over the calls."""

    def __init__(self):
        self.total, self.ok = [], []
        self.stages: dict = {}
        self.solver: dict = {}

    def add_calls(self, calls) -> None:
        """One frame's calls: ``[(seconds, ok, StageTimes or None), ...]``."""
        self.total.append(float(np.median([c[0] for c in calls])))
        self.ok.append(all(c[1] for c in calls))
        recorded = [c[2] for c in calls if c[2] is not None]
        for attr in ("stages", "solver"):
            keys = {k for t in recorded for k in getattr(t, "seconds" if attr == "stages" else "solver")}
            sums = getattr(self, attr)
            for k in keys:
                v = np.median([getattr(t, "seconds" if attr == "stages" else "solver").get(k, 0.0) for t in recorded])
                sums[k] = sums.get(k, 0.0) + float(v)

    def row(self, category, method) -> dict:
        n = len(self.total)
        return {
            "category": category, "method": method, "frames": n, "ok": float(np.mean(self.ok)),
            "total_ms": 1e3 * float(np.mean(self.total)), "total_median_ms": 1e3 * float(np.median(self.total)),
            "stages_ms": {k: 1e3 * v / n for k, v in self.stages.items()},
            "solver_ms": {k: (v / n if k.endswith(".iterations") else 1e3 * v / n) for k, v in self.solver.items()},
        }


# ---------------------------------------------------------------------------------------------
def write_profile_report(result: dict, path, provenance: Provenance) -> dict:
    """Write ``path`` (markdown) and its ``.json``; returns the overall summary (per method: mean total ms, the
    stages' shares, the smallest ratio to official)."""
    from pathlib import Path

    cfg, rows = result["config"], result["rows"]
    stages = [s for s in result["stages"] if any(s in r["stages_ms"] for r in rows)]
    solver_keys = [s for s in result["solver_stages"] if any(s in r["solver_ms"] for r in rows)]
    methods = list(cfg["methods"])
    summary = {}
    for m in methods:
        sel = [r for r in rows if r["method"] == m]
        if not sel:
            continue
        stage_sum = {s: float(np.mean([r["stages_ms"].get(s, 0.0) for r in sel])) for s in stages}
        total = float(np.mean([r["total_ms"] for r in sel]))
        ratios = [r["ratio"] for r in sel if "ratio" in r]
        summary[m] = {"total_ms": total, "stages_ms": stage_sum,
                      "min_ratio": float(min(ratios)) if ratios else None,
                      "solver_ms": {s: float(np.mean([r["solver_ms"].get(s, 0.0) for r in sel])) for s in solver_keys}}
    has_official = any("ratio" in r for r in rows)
    lines = [
        "# Profile of the exact fit: where one fit's time goes",
        "",
        f"Generated {provenance.date} by `{provenance.command}` on {provenance.machine_text}.",
        "",
        f"Frames: `ancsh bench fit`'s, {cfg['frames_per_category']} per category, level `{cfg['level']}`, seed "
        f"{cfg['seed']}: the corrupted correspondences and RANSAC seeds of `ancsh bench fit --frames "
        f"{cfg['frames_per_category']} --levels {cfg['level']} --categories {','.join(result['categories'])}"
        f"{'' if cfg['seed'] == 0 else ' --seed ' + str(cfg['seed'])}` (its frame seeds count over the categories "
        f"in this order). Methods: {', '.join(methods)} (default "
        f"`FitConfig`). Each fits every frame {cfg['repeats']} times with its stages recorded "
        "(`ancsh.solvers.stages.record_stages`): total = the frame's median call, a stage = its median over the "
        "frame's calls, both averaged over frames. Milliseconds per fit. The machine is shared: absolute times move with its load, compare "
        "columns of one run.",
        "",
        "## Overall (mean over categories)",
        "",
        "| method | total ms | " + " | ".join(stages) + " |",
        "|---|---|" + "---|" * len(stages),
    ]
    for m, s in summary.items():
        tot = sum(s["stages_ms"].values()) or 1.0
        lines.append(f"| {m} | {s['total_ms']:.2f} | " + " | ".join(
            f"{s['stages_ms'][k]:.3f} ({100 * s['stages_ms'][k] / tot:.0f}%)" for k in stages) + " |")
    lines += ["", "Solver stages (mean over categories; iterations per fit):", "",
              "| method | " + " | ".join(solver_keys) + " |", "|---|" + "---|" * len(solver_keys)]
    for m, s in summary.items():
        lines.append(f"| {m} | " + " | ".join(
            ("-" if not any(r["method"] == m and k in r["solver_ms"] for r in rows) else
             f"{s['solver_ms'][k]:.1f}" if k.endswith(".iterations") else f"{s['solver_ms'][k]:.3f}")
            for k in solver_keys) + " |")
    lines += ["", "## Per category", ""]
    head = "| category | method | ok | total ms | total median ms | " + " | ".join(stages)
    if has_official:
        head += f" | official ms (mean) | official / total | total for {TARGET_SPEEDUP:.0f}x"
    lines += [head + " |", "|---" * (head.count("|") - 1) + "|"]
    for r in rows:
        cells = [r["category"], r["method"], f"{r['ok']:.0%}", f"{r['total_ms']:.2f}", f"{r['total_median_ms']:.2f}"]
        cells += [f"{r['stages_ms'].get(k, 0.0):.3f}" for k in stages]
        if has_official:
            cells += ([f"{r['official_ms']:.0f}", f"{r['ratio']:.0f}", f"{r['official_ms'] / TARGET_SPEEDUP:.2f}"]
                      if "ratio" in r else ["-", "-", "-"])
        lines.append("| " + " | ".join(cells) + " |")
    lines += ["", "### Solver stages per category", "",
              "| category | method | " + " | ".join(solver_keys) + " |", "|---|---|" + "---|" * len(solver_keys)]
    for r in rows:
        lines.append(f"| {r['category']} | {r['method']} | " + " | ".join(
            "-" if k not in r["solver_ms"] else
            f"{r['solver_ms'][k]:.1f}" if k.endswith(".iterations") else f"{r['solver_ms'][k]:.3f}"
            for k in solver_keys) + " |")
    lines += ["", "## Stages", "", "| stage | what it holds |", "|---|---|"]
    lines += [f"| {k} | {v} |" for k, v in result["stages"].items()]
    lines += [f"| {k} | {v} |" for k, v in result["solver_stages"].items()]
    lines.append("")
    path = Path(path)
    write_text(path, "\n".join(lines))
    write_json(path.with_suffix(".json"), {"command": provenance.command, "date": provenance.date,
                                           "machine": provenance.machine, **result, "summary": summary}, indent=1)
    return summary
