"""``ancsh bench cad-auto``: ``fit-cad`` with its automatic start (no initial pose) on renders of real objects.

Protocol: for every object (the shared PartNet-Mobility objects, the first ``per_category`` of each category in
name order) one view is rendered: joint states uniform in their limits, an upright camera (the object's canonical
up is image up, as :func:`~ancsh.solvers.icp.articulated.auto_init` assumes) at an azimuth uniform over the full
circle, elevation 15-45 degrees, distance 1.6-2.2 object diagonals; a view where some part covers fewer than
``min_part_pixels`` pixels is drawn again (at most ``redraws`` times). The depth image (optionally with Kinect-like
noise, :class:`~ancsh.data.noise.DepthNoise`) is fitted exactly as ``ancsh fit-cad`` fits it
(:func:`~ancsh.solvers.icp.depth.fit_depth`, no ``--init``) at every seed of ``seeds``.

Outcome of one fit: *right* (reported ``success`` and AD-correct), *wrong but success* (reported ``success``, not
AD-correct: the failure this benchmark exists to catch), *refused* (any other status), split into refused correct
and refused wrong fits. AD-correct: the paper's AD criterion as :func:`~ancsh.studies.cad.measure.ad_correct` applies
it (Michel et al. 2015): every part's mean surface-point distance between the estimated and the true pose is below
:data:`~ancsh.studies.cad.measure.AD_THRESHOLD` (10%) of the part's diameter. Seed agreement of an object: every seed
gives the same outcome and the same fit (each pair of fits AD-equal by the same criterion, one taken as the truth of
the other).
"""

from __future__ import annotations

import json
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from ...geometry._checks import check_int
from ...model.articulated import ArticulatedModel
from .measure import AD_THRESHOLD, PartPoints, ad_correct

__all__ = ["AutoStartConfig", "AutoFitRecord", "OUTCOMES", "auto_start_objects", "measure_auto_start", "outcome",
           "render_upright_view", "summarise_auto_start", "write_auto_start_report"]

OUTCOMES = ("right", "wrong_success", "refused_correct", "refused_wrong")


@dataclass(frozen=True)
class AutoStartConfig:
    """Size of a ``bench cad-auto`` run.

    Attributes
    ----------
    per_category : int
        Objects per category (the first in name order), ``>= 1``.
    seeds : tuple of int
        ``fit-cad --seed`` values fitted on every view.
    points : int
        ``fit-cad --points``.
    noise : bool
        Kinect-like depth noise on the renders.
    image_size : (int, int)
        Rendered ``(width, height)`` (Kinect field of view).
    scene_seed : int
        Seeds the articulations and views (object ``i`` draws from ``(scene_seed, i)``).
    min_part_pixels, redraws : int
        A view must show every part with at least ``min_part_pixels`` pixels; at most ``redraws`` more draws.
    data : str or None
        Folder holding ``<category>_<id>/mobility.urdf`` objects (default: the shared data's ``partnet_mobility``).
    """

    per_category: int = 3
    seeds: tuple = (0, 1, 2)
    points: int = 3000
    noise: bool = False
    image_size: tuple = (320, 240)
    scene_seed: int = 0
    min_part_pixels: int = 100
    redraws: int = 8
    data: str | None = None

    def __post_init__(self):
        check_int(self.per_category, "per_category", minimum=1)
        check_int(self.points, "points", minimum=6)
        check_int(self.min_part_pixels, "min_part_pixels", minimum=1)
        check_int(self.redraws, "redraws", minimum=0)
        if not self.seeds:
            raise ValueError("seeds: expected at least one seed")
        for s in self.seeds:
            check_int(s, "seeds", minimum=0)
        object.__setattr__(self, "seeds", tuple(int(s) for s in self.seeds))


@dataclass(frozen=True)
class AutoFitRecord:
    """One fit of one view (see the module docstring for ``outcome``)."""

    object: str
    category: str
    seed: int
    status: str
    message: str
    correct: bool
    outcome: str
    ad_over_diameter: list
    rmse: float
    inlier_ratio: float
    time_s: float
    q: list
    q_true: list

    def to_dict(self) -> dict:
        return asdict(self)


def outcome(success: bool, correct: bool) -> str:
    """The outcome of one fit: one of :data:`OUTCOMES`."""
    if success:
        return "right" if correct else "wrong_success"
    return "refused_correct" if correct else "refused_wrong"


def auto_start_objects(config: AutoStartConfig) -> tuple[list[tuple[str, str, ArticulatedModel]], list[str]]:
    """``([(name, category, model), ...], skipped messages)``: the first ``per_category`` usable objects of each
    category (folder name ``<category>_<id>``) in name order."""
    from ...data.paths import shared_data_dir
    from ...data.urdf import load_urdf

    root = Path(config.data) if config.data is not None else shared_data_dir() / "partnet_mobility"
    if not root.is_dir():
        raise FileNotFoundError(f"data: no such folder {str(root)!r}")
    objects, skipped, counts = [], [], {}
    for path in sorted(root.glob("*/mobility.urdf")):
        name = path.parent.name
        category = name.rsplit("_", 1)[0]
        if counts.get(category, 0) >= config.per_category:
            continue
        try:
            model = load_urdf(path)
        except ValueError as exc:
            skipped.append(f"{name}: {exc}")
            continue
        if model.num_joints == 0:
            skipped.append(f"{name}: no movable joint")
            continue
        if any(p.mesh is None for p in model.parts):
            skipped.append(f"{name}: a part has no geometry")
            continue
        objects.append((name, category, model))
        counts[category] = counts.get(category, 0) + 1
    return objects, skipped


def render_upright_view(model: ArticulatedModel, rng, intrinsics, *, noise: bool, min_part_pixels: int = 100,
                        redraws: int = 8):
    """``(depth (H, W), T_cam_base, q)``: one view of ``model`` as the module docstring describes."""
    from ...data.noise import DepthNoise, apply_noise
    from ...data.render import ModelRenderer, look_at, object_extent

    renderer = ModelRenderer(model)
    R = model.R_canon_base
    for _ in range(redraws + 1):
        q = model.random_states(rng)
        center, diag = object_extent(model, q)
        az, el, dist = rng.uniform(0, 2 * np.pi), np.radians(rng.uniform(15, 45)), rng.uniform(1.6, 2.2)
        d = np.array([np.cos(el) * np.sin(az), np.sin(el), np.cos(el) * np.cos(az)])
        T = look_at(center + R.T @ (dist * diag * d), center, R.T @ np.array([0.0, 1.0, 0.0]))
        fr = renderer.render(q, T, intrinsics)
        if fr.part_pixels(model.num_parts).min() >= min_part_pixels:
            break
    depth = apply_noise(fr.depth, DepthNoise(), rng) if noise else fr.depth
    return depth, T, q


def _same_fit(pp: PartPoints, a, b) -> bool:
    return bool(ad_correct(pp, a, b)[0].all())


def measure_auto_start(config: AutoStartConfig = AutoStartConfig(), *, progress=None) -> dict:
    """Render every object once and fit it at every seed; returns ``{"records", "agreement", "objects", "skipped",
    "config"}`` (records as dicts; ``agreement``: per object, whether its seeds agree)."""
    from ...data.render import Intrinsics
    from ...solvers.icp.depth import depth_points, fit_depth
    from ...solvers.icp.template import ModelSurface
    from ...solvers.types import FitStatus

    objects, skipped = auto_start_objects(config)
    intr = Intrinsics.kinect(*config.image_size)
    records, agreement = [], {}
    for oi, (name, category, model) in enumerate(objects):
        rng = np.random.default_rng([config.scene_seed, oi])
        depth, T, q = render_upright_view(model, rng, intr, noise=config.noise, min_part_pixels=config.min_part_pixels,
                                          redraws=config.redraws)
        pts = depth_points(depth, intr)
        truth = [T @ P for P in model.forward_kinematics(q)]
        pp = PartPoints(model)
        surface = ModelSurface(model)
        fits = []
        for seed in config.seeds:
            t0 = time.perf_counter()
            res = fit_depth(model, pts, points=config.points, rng=seed, surface=surface)
            dt = time.perf_counter() - t0
            ok, ratios = ad_correct(pp, res.T_cam_parts, truth)
            success = res.status == FitStatus.SUCCESS
            rec = AutoFitRecord(name, category, seed, res.status.value, res.message, bool(ok.all()),
                                outcome(success, bool(ok.all())), [float(r) for r in ratios], float(res.rmse),
                                float(res.inlier_ratio), dt, [float(v) for v in res.q], [float(v) for v in q])
            records.append(rec.to_dict())
            fits.append((rec, res.T_cam_parts))
        agree = all(r.outcome == fits[0][0].outcome for r, _ in fits) and all(
            _same_fit(pp, fits[i][1], fits[j][1]) for i in range(len(fits)) for j in range(i + 1, len(fits)))
        agreement[name] = bool(agree)
        if progress is not None:
            progress(name, [r for r, _ in fits], agree)
    return {"records": records, "agreement": agreement, "skipped": skipped,
            "objects": [{"name": n, "category": c, "parts": m.part_names,
                         "joints": [(j.name, j.type.value) for j in m.joints]} for n, c, m in objects],
            "config": {**asdict(config), "seeds": list(config.seeds), "image_size": list(config.image_size),
                       "ad_threshold": AD_THRESHOLD}}


def summarise_auto_start(results: dict) -> dict:
    """Counts per outcome (all fits, and per category), the number of objects whose seeds agree."""
    recs = results["records"]
    total = {k: sum(r["outcome"] == k for r in recs) for k in OUTCOMES}
    cats = sorted({r["category"] for r in recs})
    per_cat = {c: {k: sum(r["outcome"] == k and r["category"] == c for r in recs) for k in OUTCOMES} for c in cats}
    return {"fits": len(recs), "total": total, "per_category": per_cat,
            "objects": len(results["agreement"]), "agree": sum(results["agreement"].values()),
            "median_time_s": float(np.median([r["time_s"] for r in recs])) if recs else float("nan")}


def write_auto_start_report(results: dict, path, provenance, *, before: dict | None = None,
                            wall_s: float | None = None) -> Path:
    """Write ``path`` (markdown) and ``path.with_suffix('.json')``; ``before`` (a former run's JSON) adds its totals
    beside this run's (with its ``note``, when it has one: what code it ran)."""
    from ...outputs import json_safe
    from ..report import write_json, write_text

    path = Path(path)
    s = summarise_auto_start(results)
    cfg = results["config"]
    head = ("| run | fits | right | wrong but success | refused (correct) | refused (wrong) | "
            "objects whose seeds agree | median s per fit |")
    rule = "| --- | --- | --- | --- | --- | --- | --- | --- |"

    def row(label, summ):
        t = summ["total"]
        return (f"| {label} | {summ['fits']} | {t['right']} | {t['wrong_success']} | {t['refused_correct']} | "
                f"{t['refused_wrong']} | {summ['agree']} of {summ['objects']} | {summ['median_time_s']:.1f} |")

    lines = [
        "# `fit-cad` with the automatic start on renders of real objects",
        "",
        f"Generated by `{provenance.command}` on {provenance.date} ({provenance.machine_text})"
        + (f" in {wall_s / 60:.1f} min" if wall_s else "") + ".",
        "",
        f"Protocol: {len(results['objects'])} shared PartNet-Mobility objects (the first {cfg['per_category']} of "
        "each category in name order), one view each: joint states uniform in their limits, an upright camera at an "
        "azimuth uniform over the full circle, elevation 15-45 degrees, distance 1.6-2.2 object diagonals, "
        f"{cfg['image_size'][0]}x{cfg['image_size'][1]} Kinect-like intrinsics, "
        + ("Kinect-like depth noise" if cfg["noise"] else "no sensor noise") + f". Every view is fitted as "
        f"`ancsh fit-cad --points {cfg['points']}` fits it (no `--init`: the automatic start) at seeds "
        f"{', '.join(str(v) for v in cfg['seeds'])}.",
        "",
        "Right: reported `success` and AD-correct -- the paper's AD criterion (Michel et al. 2015): every part's mean "
        "distance between its surface points under the estimated and the true pose is below "
        f"{100 * cfg['ad_threshold']:.0f}% of the part's diameter. Wrong but success: reported `success`, not "
        "AD-correct. Refused: any other status (correct or wrong by AD). The seeds of an object agree when every seed "
        "gives the same outcome and AD-equal fits.",
        "",
        "`fit-cad`'s status (`ArticulatedIcpConfig.instance()`, `docs/json_schema.md`): the sensor noise is estimated "
        "from the points (1.4826 x the median distance of each point to the plane of its 10 nearest neighbours); a "
        "point lies on the model within 3 of its standard deviations (at least the solver's convergence tolerance); "
        "`success` needs 80% of the points on the model and at most 20% of its visible surface unobserved "
        "(`large_residual` otherwise), no AD-distinct fit among the symmetric starts that explains the points too "
        "and is not 3 standard errors worse by McNemar's test (`ambiguous` otherwise). No threshold is fitted to "
        "these objects. Times are wall seconds on a shared machine (other jobs ran beside both runs).",
        "",
        "## Totals",
        "",
        head,
        rule,
    ]
    if before is not None:
        label = f"before (`{before.get('command', '?')}`" + (f"; {before['note']}" if before.get("note") else "") + ")"
        lines.append(row(label, summarise_auto_start(before)))
    lines += [row("this run", s), "", "## Per category (all seeds)", "",
              "| category | right | wrong but success | refused (correct) | refused (wrong) |",
              "| --- | --- | --- | --- | --- |"]
    for c, t in s["per_category"].items():
        lines.append(f"| {c} | {t['right']} | {t['wrong_success']} | {t['refused_correct']} | {t['refused_wrong']} |")
    lines += ["", "## Per object", "",
              "Outcome per seed, then the largest part AD / diameter, the inlier RMSE (model units) and the status of "
              "each seed.", "", "| object | seeds agree | outcomes | max AD / diameter | rmse | status |",
              "| --- | --- | --- | --- | --- | --- |"]
    for o in results["objects"]:
        rs = [r for r in results["records"] if r["object"] == o["name"]]
        lines.append(
            f"| {o['name']} | {'yes' if results['agreement'][o['name']] else '**no**'} | "
            + " ".join(r["outcome"] for r in rs) + " | " + " ".join(f"{max(r['ad_over_diameter']):.3f}" for r in rs)
            + " | " + " ".join(f"{r['rmse']:.2g}" for r in rs) + " | " + " ".join(r["status"] for r in rs) + " |")
    if results["skipped"]:
        lines += ["", "Skipped: " + "; ".join(results["skipped"])]
    text = "\n".join(lines) + "\n"
    write_text(path, text)
    payload = {"command": provenance.command, "date": provenance.date, "machine": provenance.machine,
               "wall_s": wall_s, "summary": s, **results}
    if before is not None:
        payload["before"] = {"command": before.get("command"), "note": before.get("note"),
                             "summary": summarise_auto_start(before)}
    write_json(path.with_suffix(".json"), json_safe(payload), indent=1, allow_nan=False)
    return path
