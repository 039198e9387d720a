"""``ancsh bench tracking``: tracking vs independent per-frame fitting on generated sequences.

For every object (procedural categories with the learned provider and the oracle, and one URDF
object with articulated ICP) it generates seeded sequences (:mod:`ancsh.data.sequences`), blanks
``gap`` frames in the middle of each (the object leaves the view and comes back: the tracker must
report them ``lost`` and re-initialise), and runs, frame by frame and interleaved (alternating
which goes first, so machine load hits both alike), the tracker and an independent fit of the
same frame: :func:`~ancsh.tracking.tracker.fit_frame` (provider + RANSAC + fit) at the category
level, the multi-start :func:`~ancsh.solvers.icp.articulated.articulated_icp` from
:func:`~ancsh.solvers.icp.articulated.auto_init` for the URDF. Errors against the ground truth
(the paper's rotation / translation per part, joint states; AD accuracy for the URDF object) over
the frames the object is in view, and frames per second of each side.

The report adds how much temporal averaging could buy at all: the frame-to-frame correlation of
the per-frame fits' signed errors and the ideal fusion bound (:mod:`.analysis`). ``--tracker`` sets
:class:`~ancsh.tracking.tracker.TrackerConfig` fields of the tracking side (a JSON object).

Measuring (:func:`run_benchmark`) and writing (:func:`write_report`) are separate.
"""

from __future__ import annotations

import json
import time
from dataclasses import asdict, dataclass, field

import numpy as np

from ..outputs import output_flags

__all__ = ["BenchConfig", "register", "run_benchmark", "summarize", "write_report"]

AD_THRESHOLD = 0.1


@dataclass(frozen=True)
class BenchConfig:
    """Size and settings of a tracking benchmark run.

    Attributes
    ----------
    categories : tuple of str
        Procedural categories (test instances).
    providers : tuple of str
        ``"learned"`` (shipped weights) and / or ``"oracle"`` (``realistic`` corruption).
    urdf : str or None
        A URDF object (instance-level tracking); ``None`` skips it.
    sequences, urdf_sequences : int
        Sequences per procedural object / of the URDF object (its cold per-frame baseline costs seconds a frame).
    length, urdf_length : int
        Frames per sequence (category level / URDF).
    gap : int
        Blank frames in the middle of each sequence (object out of view), ``>= 0``.
    network_every : int
        ``k``: the network runs on every ``k``-th tracked frame.
    seed : int
    tracker : dict
        :class:`~ancsh.tracking.tracker.TrackerConfig` fields of the tracking side.
    calibration_sequences : int
        Sequences per procedural object of the calibration of tracked frames' standard deviations
        (:func:`calibrate`; 0: none), frame seed ``calibration_seed`` (the same held-out instances, other
        sequences than the benchmark's).
    """

    categories: tuple = ("laptop", "drawer", "eyeglasses")
    providers: tuple = ("learned", "oracle")
    urdf: str | None = None
    sequences: int = 2
    urdf_sequences: int = 1
    length: int = 40
    urdf_length: int = 16
    gap: int = 3
    network_every: int = 3
    seed: int = 0
    tracker: dict = field(default_factory=dict)
    calibration_sequences: int = 0
    calibration_seed: int = 1001

    def to_dict(self) -> dict:
        return asdict(self)


def default_urdf() -> str | None:
    """The benchmark's URDF object: the shared PartNet-Mobility laptop 10101, where it exists."""
    from ..data.paths import shared_data_dir

    p = shared_data_dir() / "partnet_mobility" / "laptop_10101" / "mobility.urdf"
    return str(p) if p.is_file() else None


class _FrameOracle:
    """The oracle provider of whichever frame is current (``realistic`` corruption, seeded by the frame)."""

    def __init__(self, preset: str = "realistic"):
        self.preset, self.frame = preset, None

    @property
    def num_joints(self) -> int:
        return 0 if self.frame is None else self.frame.num_joints

    def correspond(self, observation):
        from ..solvers.providers.oracle import OracleProvider

        return OracleProvider(self.frame, self.preset, rng=self.frame.seed).correspond(observation)


def _sequence_frames(gen, seq: int, length: int, gap: int) -> list:
    frames = [gen.frame(seq * length + t) for t in range(length)]
    start = (length - gap) // 2 + length // 6
    return [(fr, start <= fr.time_index < start + gap) for fr in frames]


def _category_errors(result, frame) -> dict:
    """The paper's errors of a fit, and its signed error vectors (:func:`~ancsh.tracking.analysis.signed_errors`:
    ``rot_vec`` (M, 3) degrees, ``trans_vec`` (M, 3) object diagonals, ``state_signed`` (K,))."""
    from ..evaluation import evaluate_fit
    from ..tracking.analysis import signed_errors

    if result is None or not result.ok:
        return {"ok": False}
    e = evaluate_fit(result, frame.gt, frame.part_names, frame.joint_names)
    v = signed_errors(result, frame.gt)
    return {"ok": True, "rot_deg": [p.rot_deg for p in e.parts], "trans": [p.trans for p in e.parts],
            "state_err": [j.state_err for j in e.joints], "rot_vec": v["rot"].tolist(), "trans_vec": v["trans"].tolist(),
            "state_signed": v["state"].tolist()}


#: Quantities whose reported standard deviations the benchmark checks (:mod:`ancsh.studies.uncertainty_calibration`).
COVERAGE_QUANTITIES = ("rotation", "translation", "joint_state")


def _reported(result, tracked, provider_name: str, category: str, provider):
    """The fit with the standard deviations a user is given: the tracker's frames (``tracked``, a
    :class:`~ancsh.tracking.tracker.TrackedFrame`) as it reports them (a learned provider's inflated,
    :meth:`~ancsh.tracking.tracker.CategoryTracker.step`); a learned per-frame fit (``tracked`` ``None``)
    inflated as ``ancsh predict`` does (:func:`~ancsh.learned.inference.predict.inflate_uncertainty`); the oracle's
    fits (raw in the tracker: it has no weights) as the tracker would a learned provider's, with the
    factors of provider ``oracle-realistic`` (``-tracked-<source>`` for warm tracked frames, where measured)."""
    import dataclasses

    from ..tracking.tracker import TrackStatus

    unc = getattr(result, "uncertainty", None)
    if unc is None:
        return result
    if provider_name == "learned":
        if tracked is not None:
            return result
        from ..learned.inference.predict import inflate_uncertainty

        return inflate_uncertainty(result, category, provider)
    from ..solvers.uncertainty import first_measured_inflation

    if not unc.inflation.is_identity:
        return result
    warm = tracked is not None and tracked.status == TrackStatus.TRACKED
    inflation = first_measured_inflation((tracked_provider_key(provider_name, tracked.source) if warm else None,
                                          "oracle-realistic"), category)
    return dataclasses.replace(result, uncertainty=unc.inflated(inflation))


def _coverage_fields(result, frame) -> dict:
    """``{"d2": {quantity: [squared Mahalanobis distance of each part's / joint's error, ...]}}`` under the
    fit's reported covariance (:func:`~ancsh.studies.uncertainty_calibration.error_records`, ``reported=True``;
    ``nan`` where a variance is unbounded), and ``"inflation"``: the source of the maps applied; ``{}`` for a fit
    without an uncertainty."""
    from .uncertainty_calibration import error_records, normalised_errors

    if getattr(result, "uncertainty", None) is None:
        return {}
    records = error_records(result, frame.gt, reported=True)
    return {"d2": {q: normalised_errors(records[q]).tolist() for q in COVERAGE_QUANTITIES},
            "inflation": result.uncertainty.inflation.source}


def _instance_errors(result, frame, model, part_points) -> dict:
    from ..geometry.metrics import rotation_error_deg
    from .cad import ad_correct

    if result is None:
        return {"ok": False}
    gt_parts = [frame.T_cam_base @ T for T in model.forward_kinematics(frame.joint_states_abs)]
    correct, ratio = ad_correct(part_points, result.T_cam_parts, gt_parts, AD_THRESHOLD)
    diag = 1.0 / _diag_inverse(model)
    state = []
    for k, j in enumerate(model.joints):
        d = float(result.q[k] - frame.joint_states_abs[k])
        state.append(abs(np.degrees(d)) if j.type.value == "revolute" else abs(d) / diag)
    return {"ok": True, "rot_deg": [rotation_error_deg(A.rotation, B.rotation) for A, B in zip(result.T_cam_parts, gt_parts)],
            "trans": [float(np.linalg.norm(A.translation - B.translation)) / diag for A, B in zip(result.T_cam_parts, gt_parts)],
            "state_err": state, "ad_correct": [bool(c) for c in correct], "ad_over_diameter": [float(r) for r in ratio]}


def _diag_inverse(model) -> float:
    from ..model.canonical import canonical_space

    return canonical_space(model).T_naocs_base.scale


def _provider(name: str, category: str):
    if name == "learned":
        from ..learned.inference.provider import LearnedProvider

        return LearnedProvider(category, num_threads=1)
    return _FrameOracle()


def tracked_provider_key(provider_name: str, source: str) -> str:
    """``"learned-tracked-carried"``, ``"oracle-realistic-tracked-network"``, ...: the inflation-table provider of
    a warm tracked frame of a bench provider (:func:`ancsh.solvers.uncertainty.tracked_provider`)."""
    from ..solvers.uncertainty import tracked_provider

    return tracked_provider("learned" if provider_name == "learned" else "oracle-realistic", source)


def _sequences(config: BenchConfig, seed: int, count: int):
    """``(category, provider name, provider, sequence index, [(frame, blank), ...])`` of ``count`` sequences per
    procedural object (frame seed ``seed``; one provider per category and provider name, shared by its sequences)."""
    from ..data.generate import FrameGenerator, GenerationConfig
    from ..data.sequences import SequenceMotion

    for category in config.categories:
        gen = FrameGenerator(GenerationConfig(category=category, split="test", seed=seed,
                                              sequence=SequenceMotion(length=config.length)))
        for provider_name in config.providers:
            provider = _provider(provider_name, category)
            for seq in range(count):
                yield category, provider_name, provider, seq, _sequence_frames(gen, seq, config.length, config.gap)


def calibrate(config: BenchConfig, *, progress=None) -> dict:
    """Measure inflation maps of tracked frames' standard deviations, per provider, category and frame source.

    Tracks ``config.calibration_sequences`` sequences per object (frame seed ``config.calibration_seed``;
    tracking only) and collects, of every warm (``tracked``) in-view frame that reports a covariance, the raw
    error records (:func:`ancsh.studies.uncertainty_calibration.error_records`) under
    :func:`tracked_provider_key`; :func:`ancsh.studies.uncertainty_calibration.summarize` fits the within-part
    correlation and the maps as for single frames (its "test" split is the calibration itself here:
    the benchmark's own sequences are the test).

    Returns
    -------
    dict
        ``{"summary": summarize(...)'s dict (without its d2), "counts": {category: {provider key: frames}}}``.
    """
    from ..solvers.types import Observation
    from .uncertainty_calibration import QUANTITIES, error_records
    from .uncertainty_calibration import summarize as fit_maps
    from ..tracking.tracker import CategoryTracker, TrackerConfig, TrackStatus

    say = progress or (lambda s: None)
    tcfg = TrackerConfig(network_every=config.network_every, **config.tracker)
    records, counts = {}, {}
    for category, provider_name, provider, seq, frames in _sequences(config, config.calibration_seed,
                                                                     config.calibration_sequences):
        say(f"calibration: {category} / {provider_name} / sequence {seq}")
        tracker = CategoryTracker(provider, tcfg, category=category, rng=config.calibration_seed)
        for fr, blank in frames:
            if isinstance(provider, _FrameOracle):
                provider.frame = fr
            tracked = tracker.step(Observation(np.zeros((0, 3)) if blank else fr.points))
            r = tracked.result
            if blank or tracked.status != TrackStatus.TRACKED or getattr(r, "uncertainty", None) is None:
                continue
            key = tracked_provider_key(provider_name, tracked.source)
            cal = records.setdefault(category, {}).setdefault(key, {"calibration": {q: [] for q in QUANTITIES}})
            for q, rs in error_records(r, fr.gt).items():
                cal["calibration"][q] += rs
            counts.setdefault(category, {}).setdefault(key, 0)
            counts[category][key] += 1
    for per_key in records.values():
        for splits in per_key.values():
            splits["test"] = splits["calibration"]
    summary = fit_maps({"records": records})
    summary.pop("d2")
    return {"summary": summary, "counts": counts}


def run_benchmark(config: BenchConfig, *, progress=None) -> dict:
    """Run the benchmark; returns ``{"config", "machine", "records"}`` (one record per frame and method)."""
    from .._machine import machine_facts
    from ..solvers.types import Observation
    from ..tracking.tracker import CategoryTracker, TrackerConfig, fit_frame

    say = progress or (lambda s: None)
    machine_start = machine_facts()
    records = []
    tcfg = TrackerConfig(network_every=config.network_every, **config.tracker)
    for category, provider_name, provider, seq, frames in _sequences(config, config.seed, config.sequences):
        say(f"{category} / {provider_name} / sequence {seq}: {len(frames)} frames")
        tracker = CategoryTracker(provider, tcfg, category=category, rng=config.seed)
        for fr, blank in frames:
            if isinstance(provider, _FrameOracle):
                provider.frame = fr
            obs = Observation(np.zeros((0, 3)) if blank else fr.points)
            out = {}

            def run_tracking():
                t0 = time.perf_counter()
                tracked = tracker.step(obs)
                out["tracking"] = (tracked.result, time.perf_counter() - t0, tracked)

            def run_per_frame():
                t0 = time.perf_counter()
                result, _ = fit_frame(provider, obs, tcfg, category, config.seed)
                out["per_frame"] = (result, time.perf_counter() - t0, None)

            for run in ((run_tracking, run_per_frame) if fr.time_index % 2 == 0 else (run_per_frame, run_tracking)):
                run()
            for method, (result, dt, tracked) in out.items():
                rec = {"object": category, "provider": provider_name, "sequence": seq, "t": fr.time_index,
                       "blank": blank, "method": method, "time_s": dt,
                       "status": None if result is None else result.status.value,
                       "track": None if tracked is None else tracked.status.value,
                       "source": None if tracked is None else tracked.source,
                       "iterations": None if result is None else int(result.iterations)}
                rec.update(_category_errors(result, fr) if not blank else {"ok": result is not None and result.ok})
                if not blank and rec["ok"]:
                    rec.update(_coverage_fields(_reported(result, tracked, provider_name, category, provider), fr))
                records.append(rec)
    if config.urdf is not None:
        records += _urdf_records(config, say)
    return {"config": config.to_dict(), "tracker": asdict(tcfg) | {"fit": asdict(tcfg.fit)},
            "machine": {"start": machine_start, "end": machine_facts()}, "records": records}


def _urdf_records(config: BenchConfig, say) -> list:
    from ..data.generate import FrameGenerator, GenerationConfig
    from ..data.sequences import SequenceMotion
    from ..solvers.icp.articulated import articulated_icp, auto_init
    from .cad import PartPoints
    from ..tracking.instance import InstanceTracker, InstanceTrackerConfig

    gen = FrameGenerator(GenerationConfig(urdf=config.urdf, seed=config.seed, sequence=SequenceMotion(length=config.urdf_length)))
    model, _ = gen.instance(0)
    name = gen.config.name
    part_points = PartPoints(model, 500, config.seed)
    icfg = InstanceTrackerConfig()
    records = []
    for seq in range(config.urdf_sequences):
        frames = _sequence_frames(gen, seq, config.urdf_length, config.gap)
        say(f"{name} (URDF) / sequence {seq}: {len(frames)} frames")
        tracker = InstanceTracker(model, icfg, rng=config.seed)
        rng = np.random.default_rng(config.seed)
        for fr, blank in frames:
            pts = np.zeros((0, 3)) if blank else fr.points
            out = {}

            def run_tracking():
                t0 = time.perf_counter()
                tracked = tracker.step(pts)
                out["tracking"] = (tracked.result, time.perf_counter() - t0, tracked)

            def run_per_frame():
                t0 = time.perf_counter()
                result = None
                if pts.shape[0] >= icfg.min_points:
                    result = articulated_icp(model, pts, auto_init(model, pts), config=icfg.cold, rng=rng,
                                             surface=tracker.template.surface)
                out["per_frame"] = (result, time.perf_counter() - t0, None)

            for run in ((run_tracking, run_per_frame) if fr.time_index % 2 == 0 else (run_per_frame, run_tracking)):
                run()
            for method, (result, dt, tracked) in out.items():
                rec = {"object": name, "provider": "urdf", "sequence": seq, "t": fr.time_index, "blank": blank,
                       "method": method, "time_s": dt, "status": None if result is None else result.status.value,
                       "track": None if tracked is None else tracked.status.value,
                       "source": None if tracked is None else tracked.source,
                       "iterations": None if result is None else int(result.iterations)}
                rec.update(_instance_errors(result, fr, model, part_points) if not blank else {"ok": result is not None})
                records.append(rec)
    return records


# ---------------------------------------------------------------------------------------------
# summary and report
# ---------------------------------------------------------------------------------------------
def _mean(values) -> float:
    from ..evaluation import aggregate

    return aggregate(values).mean


def summarize(report: dict) -> dict:
    """Per (object, provider): both methods' mean errors over the in-view frames, frames/s, ratios,
    lost / re-initialised frames and whether every loss was recovered."""
    rows = []
    recs = report["records"]
    keys = sorted({(r["object"], r["provider"]) for r in recs}, key=lambda k: (k[1] == "urdf", k[1], k[0]))
    for obj, prov in keys:
        row = {"object": obj, "provider": prov}
        for method in ("tracking", "per_frame"):
            sel = [r for r in recs if r["object"] == obj and r["provider"] == prov and r["method"] == method]
            view = [r for r in sel if not r["blank"]]
            good = [r for r in view if r["ok"]]
            m = {"frames": len(sel), "in_view": len(view), "failed": len(view) - len(good),
                 "fps": len(sel) / sum(r["time_s"] for r in sel),
                 "rot_deg": _mean([np.mean(r["rot_deg"]) for r in good]),
                 "trans": _mean([np.mean(r["trans"]) for r in good]),
                 "state_err": _mean([np.mean(r["state_err"]) for r in good if r["state_err"]]),
                 # failed in-view frames count as wrong
                 "ad_accuracy": (sum(all(r["ad_correct"]) for r in good) / len(view)) if prov == "urdf" and view else None}
            m["ms_median"] = _median_ms(view)
            if method == "tracking":
                # warm frames by where their correspondences came from (URDF: "model")
                for source in ("network", "carried", "model", "template"):
                    m[f"ms_{source}"] = _median_ms([r for r in view if r["track"] == "tracked" and r["source"] == source])
                m["lost"] = sum(r["track"] == "lost" for r in sel)
                m["lost_in_view"] = sum(r["track"] == "lost" for r in view)
                m["reinitialised"] = sum(r["track"] == "reinitialised" for r in sel)
                m["network_frames"] = sum(r["source"] == "network" for r in sel)
                m["recovered"] = _recovered(sel)
            row[method] = m
        if prov != "urdf":
            row["coverage"] = _coverage_summary([r for r in recs if r["object"] == obj and r["provider"] == prov])
        t, p = row["tracking"], row["per_frame"]
        row["ratio"] = {k: (t[k] / p[k] if p[k] else float("nan")) for k in ("rot_deg", "trans", "state_err")}
        row["speedup"] = t["fps"] / p["fps"]
        if prov != "urdf":
            row["correlation"] = {method: _correlation([r for r in recs if r["object"] == obj and r["provider"] == prov
                                                        and r["method"] == method]) for method in ("per_frame", "tracking")}
        rows.append(row)
    return {"rows": rows}


def _coverage_summary(records) -> list:
    """Coverage of the reported standard deviations, per method and (tracking) per frame source:
    ``[{"method", "source", "fits", "with_std", quantity: [1 sigma, 2 sigma] or None, "n_" + quantity}, ...]``
    over the in-view frames with an accepted fit (:func:`~ancsh.studies.uncertainty_calibration.coverage`;
    unbounded variances left out)."""
    from .uncertainty_calibration import coverage

    out = []
    for method in ("tracking", "per_frame"):
        good = [r for r in records if r["method"] == method and not r["blank"] and r["ok"]]
        sources = [None] + (sorted({r["source"] for r in good}) if method == "tracking" else [])
        for source in sources:
            sel = [r for r in good if source is None or r["source"] == source]
            if not sel:
                continue
            have = [r for r in sel if r.get("d2")]
            row = {"method": method, "source": source or "all", "fits": len(sel), "with_std": len(have)}
            for q in COVERAGE_QUANTITIES:
                d2 = np.array([np.nan if v is None else v for r in have for v in r["d2"][q]], dtype=np.float64)
                row["n_" + q] = int(np.isfinite(d2).sum())
                row[q] = coverage(d2, q).tolist() if row["n_" + q] else None
            out.append(row)
    return out


CORRELATION_KINDS = (("rot_vec", "rotation"), ("trans_vec", "translation"), ("state_signed", "joint state"))


def _correlation(records) -> dict:
    """Frame-to-frame correlation of the signed errors of one method's records
    (:func:`~ancsh.tracking.analysis.error_correlation`): runs of consecutive in-view frames with a fit,
    one run per part (joint) and sequence; ``{kind: CorrelationStudy.to_dict()}``."""
    from ..tracking.analysis import error_correlation

    out = {}
    for key, kind in CORRELATION_KINDS:
        runs = []
        for seq in sorted({r["sequence"] for r in records}):
            current = []
            for r in sorted((r for r in records if r["sequence"] == seq), key=lambda r: r["t"]) + [None]:
                if r is not None and not r["blank"] and r["ok"] and key in r:
                    current.append(np.asarray(r[key], dtype=np.float64).reshape(len(r[key]), -1))
                    continue
                if current:
                    stack = np.stack(current)  # (T, parts or joints, d)
                    runs += [stack[:, i, :] for i in range(stack.shape[1])]
                current = []
        if runs and sum(len(x) for x in runs):
            out[kind] = error_correlation(runs).to_dict()
    return out


def _median_ms(records) -> float | None:
    """Median time of the records in milliseconds (``None`` without any)."""
    return 1e3 * float(np.median([r["time_s"] for r in records])) if records else None


def _ms_cell(m: dict, method: str) -> str:
    """The table's median-milliseconds cell: warm network / carried frames (URDF: warm) of tracking, all in-view frames of per-frame fitting."""
    if method != "tracking":
        return _fmt(m["ms_median"], 0)
    if m.get("ms_model") is not None:
        return f"warm {_fmt(m['ms_model'], 0)}"
    if m.get("ms_template") is not None and m.get("ms_network") is None:
        return f"template {_fmt(m['ms_template'], 0)}"
    return f"{_fmt(m.get('ms_network'), 0)} / {_fmt(m.get('ms_carried'), 0)}"


def _recovered(records) -> bool:
    """Every run of lost frames in a sequence is followed by a re-initialised frame (before the sequence ends)."""
    for seq in {r["sequence"] for r in records}:
        seq_recs = sorted((r for r in records if r["sequence"] == seq), key=lambda r: r["t"])
        lost = False
        for r in seq_recs:
            if r["track"] == "lost":
                lost = True
            elif lost and r["track"] in ("reinitialised", "initialised"):
                lost = False
        if lost:
            return False
    return True


def _fmt(v, digits=2) -> str:
    if v is None or (isinstance(v, float) and not np.isfinite(v)):
        return "—"
    return f"{v:.{digits}f}"


def write_report(report: dict, summary: dict, path, *, command: str, calibration: dict | None = None,
                 installed: bool = False) -> str:
    """Write the markdown table (and ``.json`` next to it: config, machine, summary, records, calibration);
    returns the markdown. ``calibration``: :func:`calibrate`'s result (``installed``: its maps were installed
    before the benchmark's sequences ran, so the coverage table tests them)."""
    from pathlib import Path

    from .._machine import describe_machine

    cfg, rows = report["config"], summary["rows"]
    m0, m1 = report["machine"]["start"], report["machine"]["end"]
    lines = [
        "# Tracking vs independent per-frame fitting",
        "",
        f"Command: `{command}`",
        "",
        f"Machine: {describe_machine(m0)}, {m1.get('load_average_1min')} at the end (the machine is shared: both sides are "
        "measured interleaved, frame by frame, alternating which goes first). Times are per frame from the observed points "
        "(rendering, depth reading and object isolation excluded, identical for both sides); one torch thread.",
        "",
        f"Sequences: {cfg['sequences']} per object, {cfg['length']} frames (URDF: {cfg['urdf_sequences']} of "
        f"{cfg['urdf_length']}) at 30 frames/s "
        f"(`ancsh data generate --sequence-length`: joint open/close cycles within the limits, smooth camera drift, "
        f"Kinect-like noise), test instances, seed {cfg['seed']}; {cfg['gap']} blank frames (the object out of view) in "
        "each, after which the tracker must re-initialise. Errors are means over the in-view frames with an accepted fit "
        "(rotation in degrees and translation in object diagonals, averaged over parts; joint state in degrees for "
        "revolute joints, object diagonals for prismatic ones); `failed` counts in-view frames without one.",
        "",
        f"Tracking: category level -- network (or oracle) every k = {cfg['network_every']} frames, correspondences "
        f"carried by the previous fit in between, warm-started `exact_reduced` fits with {_prior_words(report['tracker'])}"
        f"; {_fusion_words(report['tracker'])}; categories "
        f"{', '.join(report['tracker'].get('template_categories') or ()) or 'none'} instead carry the "
        "category template refined at every (re-)initialisation (`refine_fit`, seconds, once) by warm articulated ICP, the "
        "network only re-initialising (median ms: template frames). Per frame: provider + RANSAC + `exact_reduced` on "
        "every frame. URDF -- warm-started articulated ICP "
        "(`InstanceTracker`); per frame: the multi-start cold articulated ICP from `auto_init` views. AD accuracy: every "
        f"part's AD below {AD_THRESHOLD} of its diameter, failed frames counted wrong.",
        "",
        "Median ms: the median time of an in-view frame; for tracking, of the warm frames fitted on the network's (or "
        "oracle's) correspondences / on carried ones (URDF: warm frames), re-initialisations excluded.",
        "",
        "| object | provider | method | frames/s | median ms | rot (deg) | trans | joint state | AD acc. | failed | lost / reinit. | recovered |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for row in rows:
        for method in ("tracking", "per_frame"):
            m = row[method]
            lost = f"{m['lost']} / {m['reinitialised']}" if method == "tracking" else ""
            rec = ("yes" if m["recovered"] else "**no**") if method == "tracking" else ""
            lines.append(f"| {row['object']} | {row['provider']} | {method.replace('_', '-')} | {_fmt(m['fps'], 1)} | {_ms_cell(m, method)} | "
                         f"{_fmt(m['rot_deg'])} | {_fmt(m['trans'], 3)} | {_fmt(m['state_err'], 2)} | "
                         f"{_fmt(m['ad_accuracy'], 2)} | {m['failed']}/{m['in_view']} | {lost} | {rec} |")
        r = row["ratio"]
        lines.append(f"| {row['object']} | {row['provider']} | **tracking / per-frame** | {_fmt(row['speedup'], 1)}x | | "
                     f"{_fmt(r['rot_deg'])} | {_fmt(r['trans'])} | {_fmt(r['state_err'])} | | | | |")
    lines += ["", "## Targets", ""]
    lines += _targets(rows, cfg)
    lines += _coverage_table(rows)
    if calibration is not None:
        lines += _calibration_table(calibration, cfg, installed)
    lines += _correlation_table(rows)
    text = "\n".join(lines) + "\n"
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    from ..outputs import write_bytes_atomically

    write_bytes_atomically(path, text.encode())
    payload = {"command": command, "config": cfg, "tracker": report["tracker"], "machine": report["machine"],
               "summary": summary, "calibration": calibration, "records": report["records"]}
    from ..outputs import json_safe

    write_bytes_atomically(path.with_suffix(".json"), json.dumps(json_safe(payload), separators=(",", ":")).encode())
    return text


def _prior_words(tracker: dict) -> str:
    """How the report names the tracker's temporal prior (``TrackerConfig`` fields of the run)."""
    w, wq = tracker.get("temporal_weight", 0.0), tracker.get("temporal_state_weight", 0.0)
    if not w and not wq:
        return "no temporal prior"
    parts = [f"pose {w:g}"] + ([f"joint state {wq:g}"] if wq else ["no joint-state part"])
    return f"the constant-velocity temporal prior ({', '.join(parts)})"


def _fusion_words(tracker: dict) -> str:
    """How the report names the fusion of network frames (``TrackerConfig.fusion_weight``)."""
    w = tracker.get("fusion_weight", 0.0)
    if not w:
        return "network frames fitted on the network's correspondences alone"
    return (f"network frames fused: the network's correspondences and, with weight {w:g}, the carried ones in one fit "
            "(a recursive weighted mean over the network frames)")


def _coverage_table(rows) -> list:
    """The markdown section of the reported standard deviations' coverage (:func:`_coverage_summary`)."""
    from .uncertainty_calibration import COVERAGE_TARGETS

    have = [r for r in rows if r.get("coverage")]
    if not have:
        return []
    lines = ["", "## Coverage of the reported standard deviations", "",
             "How often the truth lies within the reported 1σ / 2σ (%, target 68 / 95, within 10 points: issue 15), over "
             "the in-view frames with an accepted fit, per part (rotation, translation of `T_cam_npcs`) and joint (state): "
             "the squared Mahalanobis distance of the error under the reported covariance against the chi-square "
             "quantiles (`ancsh bench uncertainty`'s definitions). What is reported: the tracker's frames as it returns "
             "them (learned: inflated by the factors of `ancsh/weights/uncertainty_inflation.json`, provider "
             "`learned-tracked-<source>` for warm frames where measured, else `learned` -- `learned-template` for the "
             "carried category template), learned per-frame fits inflated as by `ancsh predict`; the oracle's fits by "
             "the factors of provider `oracle-realistic` (`oracle-realistic-tracked-<source>` likewise). `with std`: fits "
             "that report one, of the accepted fits; by source: the tracker's frames by where their correspondences "
             "came from (`network`: the cold and warm network frames).", "",
             "| object | provider | method | source | with std | rotation | translation | joint state |",
             "|---|---|---|---|---|---|---|---|"]

    def cell(c, q):
        v = c[q]
        if v is None:
            return "—"
        mark = "" if all(abs(a - b) <= 0.10 for a, b in zip(v, COVERAGE_TARGETS)) else " **x**"
        return f"{100 * v[0]:.0f} / {100 * v[1]:.0f}{mark} ({c['n_' + q]})"

    for row in have:
        for c in row["coverage"]:
            lines.append(f"| {row['object']} | {row['provider']} | {c['method'].replace('_', '-')} | {c['source']} | "
                         f"{c['with_std']}/{c['fits']} | " + " | ".join(cell(c, q) for q in COVERAGE_QUANTITIES) + " |")
    lines += ["", "**x**: outside 10 points of the target at 1σ or 2σ; in brackets the number of errors scored."]
    return lines


def _calibration_table(calibration: dict, cfg: dict, installed: bool) -> list:
    """The markdown section of the tracked frames' inflation maps (:func:`calibrate`)."""
    from .uncertainty_calibration import describe_sigma_map

    rows = calibration["summary"]["rows"]
    lines = ["", "## Calibration of tracked frames' standard deviations", "",
             f"Measured on {cfg['calibration_sequences']} other sequences per object (frame seed "
             f"{cfg['calibration_seed']}, the same held-out instances; tracking only), per provider, object and source "
             "of the warm tracked frames, as `ancsh bench uncertainty` measures single frames (within-part correlation "
             "rho, then per quantity the map of the raw sigmas that brings the calibration coverage nearest 68 / 95 %). A "
             "carried frame's raw covariance counts the carried rows as observations, and a fused network frame's "
             "counts them beside the network's: both repeat earlier errors, so their raw sigmas are far too small. "
             + ("These maps were installed (`ancsh/weights/uncertainty_inflation.json`, providers `*-tracked-<source>`) "
                "before the benchmark's sequences ran: the coverage table above tests them on other sequences."
                if installed else "These maps were **not** installed (no `--install`): the coverage table above used "
                "the table as it was."), "",
             "| object | provider | quantity | n | raw 1σ / 2σ (%) | rho | map | inflated 1σ / 2σ (%) |",
             "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        if r["quantity"] not in COVERAGE_QUANTITIES:
            continue
        per = "per joint" if r["quantity"].startswith("joint") else "per part"
        raw, inf = r["raw"], r["calibration_inflated"]
        lines.append(f"| {r['category']} | {r['provider']} | {r['quantity']} | {r['n_calibration']} | "
                     f"{100 * raw[0]:.0f} / {100 * raw[1]:.0f} | {r['correlation']:g} | "
                     f"{describe_sigma_map(r['sigma_map'], per)} | {100 * inf[0]:.0f} / {100 * inf[1]:.0f} |")
    return lines


def _correlation_table(rows) -> list:
    """The markdown section of the per-frame errors' frame-to-frame correlation (see :mod:`.analysis`)."""
    from ..tracking.analysis import WINDOWS

    have = [r for r in rows if r.get("correlation", {}).get("per_frame")]
    if not have:
        return []
    lags = (1, 2, 3, 5, 10)
    lines = ["", "## How much temporal averaging can buy: frame-to-frame correlation of the per-frame errors", "",
             "Signed errors of the independent per-frame fits (per part the rotation error vector `log(R R_gt^T)` and "
             "the translation error vector, per joint the signed joint-state error), over runs of consecutive in-view "
             "frames. `rho(l)` = E[e_t . e_t+l] / E[|e_t|^2] (raw: a per-sequence bias counts as correlation; centred: "
             "each run's mean removed). Ideal fusion N: mean |mean of the last N frames' errors| / mean |error| -- what "
             "averaging the per-frame estimates over N frames would reach relative to per-frame fitting if the motion "
             "between frames were known exactly (`all`: every frame so far); tracking on these providers' outputs cannot "
             "beat it. (Averaging N frames of correlation rho leaves the variance fraction rho + (1 - rho) / N.)", "",
             "| object | provider | error | raw rho " + "/".join(f"l{l}" for l in lags) + " | centred rho "
             + "/".join(f"l{l}" for l in lags) + " | ideal fusion " + "/".join(f"N={n}" for n in WINDOWS) + "/all |",
             "|---|---|---|---|---|---|"]
    for row in have:
        for kind, c in row["correlation"]["per_frame"].items():
            raw = "/".join(_fmt(c["raw"][l - 1]) if l <= len(c["raw"]) else "—" for l in lags)
            cen = "/".join(_fmt(c["centred"][l - 1]) if l <= len(c["centred"]) else "—" for l in lags)
            fus = "/".join(_fmt(c["fusion"][str(n)]) for n in WINDOWS + ("all",))
            lines.append(f"| {row['object']} | {row['provider']} | {kind} | {raw} | {cen} | {fus} |")
    return lines


def _targets(rows, cfg) -> list:
    out = []
    for row in rows:
        t, p, r = row["tracking"], row["per_frame"], row["ratio"]
        errs = {k: v for k, v in r.items() if np.isfinite(v)}
        worst = max(errs, key=errs.get) if errs else None
        err_ok = bool(errs) and all(v <= 0.8 for v in errs.values())
        name = f"{row['object']} / {row['provider']}"
        line = (f"- {name}: tracking error {'<=' if err_ok else '**not** <='} 0.8x per-frame "
                f"(worst ratio {_fmt(errs.get(worst))} on {worst}); ")
        if row["provider"] == "learned":
            line += f"{_fmt(t['fps'], 1)} frames/s with the network every k = {cfg['network_every']} frames (target >= 25: " \
                    f"{'met' if t['fps'] >= 25 else '**missed**'}); "
        if row["provider"] == "urdf":
            warm = 1e3 / t["ms_model"] if t.get("ms_model") else float("nan")
            line += (f"warm frames {_fmt(warm, 1)} frames/s (median; target >= 10: {'met' if warm >= 10 else '**missed**'}), "
                     f"{_fmt(t['fps'], 1)} frames/s over the sequence with its cold (re-)initialisations, vs "
                     f"{_fmt(p['fps'], 2)} cold; AD accuracy {_fmt(t['ad_accuracy'])} vs cold "
                     f"{_fmt(p['ad_accuracy'])} ({'equal or better' if t['ad_accuracy'] >= p['ad_accuracy'] else '**worse**'}); ")
        line += (f"{t['lost']} lost frames ({t['lost_in_view']} with the object in view), {t['reinitialised']} "
                 f"re-initialisations, {'every loss recovered' if t['recovered'] else '**a loss not recovered**'}.")
        out.append(line)
    return out


# ---------------------------------------------------------------------------------------------
# command line
# ---------------------------------------------------------------------------------------------
def register(sub) -> None:
    """Add ``tracking`` to the ``ancsh bench`` sub-commands."""
    p = sub.add_parser("tracking", help="tracking vs independent per-frame fitting on generated sequences")
    p.add_argument("--categories", default="laptop,drawer,eyeglasses", help="procedural categories (comma-separated)")
    p.add_argument("--providers", default="learned,oracle", help="learned and/or oracle (comma-separated)")
    p.add_argument("--urdf", default="default",
                   help="URDF object for instance-level tracking ('default': the shared laptop_10101; 'none': skip)")
    p.add_argument("--sequences", type=int, default=2, help="sequences per object (default 2)")
    p.add_argument("--length", type=int, default=40, help="frames per sequence (default 40)")
    p.add_argument("--urdf-length", type=int, default=16, help="frames per URDF sequence (default 16)")
    p.add_argument("--urdf-sequences", type=int, default=1, help="URDF sequences (default 1)")
    p.add_argument("--gap", type=int, default=3, help="blank frames in the middle of each sequence (default 3)")
    p.add_argument("-k", "--network-every", type=int, default=3, help="network on every k-th tracked frame (default 3)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--tracker", default=None, metavar="JSON",
                   help="TrackerConfig settings of the tracking side, a JSON object, e.g. '{\"temporal_weight\": 0.1}' "
                        "(default: TrackerConfig's defaults)")
    p.add_argument("--calibration-sequences", type=int, default=0,
                   help="first measure inflation maps of tracked frames' standard deviations on this many other "
                        "sequences per procedural object (default 0: none)")
    p.add_argument("--calibration-seed", type=int, default=1001, help="frame seed of the calibration sequences (default 1001)")
    p.add_argument("--install", action="store_true",
                   help="install the measured maps in ancsh/weights/uncertainty_inflation.json before the benchmark's "
                        "sequences run (needs --calibration-sequences)")
    p.add_argument("--out", default=None, help="markdown report path (default: a fresh ancsh_results/bench-tracking-<time>/)")
    p.add_argument("--update-docs", action="store_true", help="write docs/results/tracking.md (when --out is not given)")
    p.set_defaults(func=run)


def _command(args) -> str:
    parts = ["ancsh bench tracking"]
    defaults = {"categories": "laptop,drawer,eyeglasses", "providers": "learned,oracle", "urdf": "default", "sequences": 2,
                "length": 40, "urdf_length": 16, "urdf_sequences": 1, "gap": 3, "network_every": 3, "seed": 0,
                "calibration_sequences": 0, "calibration_seed": 1001}
    for key, default in defaults.items():
        if getattr(args, key) != default:
            parts.append(f"--{key.replace('_', '-')} {getattr(args, key)}")
    if args.tracker:
        parts.append(f"--tracker '{json.dumps(_tracker_settings(args.tracker), sort_keys=True)}'")
    if args.install:
        parts.append("--install")
    parts += output_flags(args.out, update_docs=args.update_docs)
    return " ".join(parts)


def _tracker_settings(text: str | None) -> dict:
    """``--tracker``'s JSON object (``{}`` without it); unknown or invalid settings raise ``ValueError``."""
    from ..tracking.tracker import TrackerConfig

    if not text:
        return {}
    try:
        settings = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ValueError(f"--tracker: expected a JSON object, got {text!r} ({exc})") from None
    if not isinstance(settings, dict):
        raise ValueError(f"--tracker: expected a JSON object, got {text!r}")
    known = {f for f in TrackerConfig.__dataclass_fields__} - {"network_every", "fit"}
    unknown = sorted(set(settings) - known)
    if unknown:
        raise ValueError(f"--tracker: unknown setting(s) {unknown} (known: {sorted(known)}; -k sets network_every)")
    TrackerConfig(**settings)  # validates the values
    return settings


def run(args) -> int:
    from ..outputs import report_path

    urdf = default_urdf() if args.urdf == "default" else None if args.urdf == "none" else args.urdf
    if args.urdf == "default" and urdf is None:
        print("bench tracking: the shared laptop_10101 URDF is not available; the URDF rows are skipped")
    providers = tuple(p.strip() for p in args.providers.split(",") if p.strip())
    for p in providers:
        if p not in ("learned", "oracle"):
            raise ValueError(f"--providers: expected learned and/or oracle, got {p!r}")
    config = BenchConfig(categories=tuple(c.strip() for c in args.categories.split(",") if c.strip()), providers=providers,
                         urdf=urdf, sequences=args.sequences, urdf_sequences=args.urdf_sequences, length=args.length, urdf_length=args.urdf_length, gap=args.gap,
                         network_every=args.network_every, seed=args.seed, tracker=_tracker_settings(args.tracker),
                         calibration_sequences=args.calibration_sequences, calibration_seed=args.calibration_seed)
    if args.calibration_sequences < 0:
        raise ValueError(f"--calibration-sequences: expected an integer >= 0, got {args.calibration_sequences}")
    if args.install and not args.calibration_sequences:
        raise ValueError("--install: nothing to install without --calibration-sequences")
    command = _command(args)
    out = report_path(args.out, update_docs=args.update_docs, docs_name="tracking.md", command="bench-tracking")
    t0 = time.perf_counter()
    calibration = None
    if args.calibration_sequences:
        calibration = calibrate(config, progress=lambda s: print(s, flush=True))
        if args.install:
            from .uncertainty_calibration import CalibrationConfig, install
            from ..tracking.tracker import TrackerConfig

            tformulation = TrackerConfig(**config.tracker).formulation
            print(f"installed the maps of tracked frames in {install(calibration['summary'], CalibrationConfig(formulation=tformulation), command)}")
    report = run_benchmark(config, progress=lambda s: print(s, flush=True))
    summary = summarize(report)
    text = write_report(report, summary, out, command=command, calibration=calibration, installed=args.install)
    print(text)
    print(f"wrote {out} and {out.with_suffix('.json')} in {time.perf_counter() - t0:.0f} s")
    return 0
