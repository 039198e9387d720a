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

import time
from dataclasses import asdict, dataclass, field

import numpy as np


__all__ = ["BenchConfig", "run_benchmark", "calibrate", "default_urdf", "tracked_provider_key", "AD_THRESHOLD",
           "COVERAGE_QUANTITIES"]

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
    refiner : str or None
        With the tracker's ``refine_network``: the learned provider's refinement network file (default: the
        category's shipped one).
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
    refiner: str | None = None

    def to_dict(self) -> dict:
        return asdict(self)


def default_urdf() -> str | None:
    """The benchmark's URDF object: the shared PartNet-Mobility laptop 10101, where it exists."""
    from ...data.paths import shared_data_dir

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
        from ...solvers.providers.oracle import OracleProvider

        return OracleProvider(self.frame, self.preset, rng=self.frame.seed).correspond(observation)


def _sequence_frames(gen, seq: int, length: int, gap: int) -> list:
    frames = [gen.frame(seq * length + t) for t in range(length)]
    start = (length - gap) // 2 + length // 6
    return [(fr, start <= fr.time_index < start + gap) for fr in frames]


def _category_errors(result, frame) -> dict:
    """The paper's errors of a fit, and its signed error vectors (:func:`~ancsh.tracking.analysis.signed_errors`:
    ``rot_vec`` (M, 3) degrees, ``trans_vec`` (M, 3) object diagonals, ``state_signed`` (K,))."""
    from ...evaluation import evaluate_fit
    from ...tracking.analysis import signed_errors

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
    inflated as ``ancsh predict`` does (:func:`~ancsh.learned.inference.candidate.inflate_uncertainty`); the oracle's
    fits (raw in the tracker: it has no weights) as the tracker would a learned provider's, with the
    factors of provider ``oracle-realistic`` (``-tracked-<source>`` for warm tracked frames, where measured)."""
    import dataclasses

    from ...tracking.tracker import TrackStatus

    unc = getattr(result, "uncertainty", None)
    if unc is None:
        return result
    if provider_name == "learned":
        if tracked is not None:
            return result
        from ...learned.inference.predict import inflate_uncertainty

        return inflate_uncertainty(result, provider.category_info, provider)
    from ...solvers.uncertainty import first_measured_inflation

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
    from ..uncertainty_calibration import error_records, normalised_errors

    if getattr(result, "uncertainty", None) is None:
        return {}
    records = error_records(result, frame.gt, reported=True)
    return {"d2": {q: normalised_errors(records[q]).tolist() for q in COVERAGE_QUANTITIES},
            "inflation": result.uncertainty.inflation.source}


def _instance_errors(result, frame, model, part_points) -> dict:
    from ...geometry.metrics import rotation_error_deg
    from ..cad import ad_correct

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
    from ...model.canonical import canonical_space

    return canonical_space(model).T_naocs_base.scale


def _provider(name: str, category: str, config: BenchConfig):
    if name == "learned":
        from ...learned.inference.provider import LearnedProvider

        if config.tracker.get("refine_network"):
            return LearnedProvider(category, num_threads=1, refine="network", refiner=config.refiner)
        return LearnedProvider(category, num_threads=1)
    if config.tracker.get("refine_network"):
        raise ValueError("tracker.refine_network: the oracle provider has no refinement network (use the learned one)")
    return _FrameOracle()


def tracked_provider_key(provider_name: str, source: str) -> str:
    """``"learned-tracked-carried"``, ``"oracle-realistic-tracked-network"``, ...: the inflation-table provider of
    a warm tracked frame of a bench provider (:func:`ancsh.solvers.uncertainty.tracked_provider`)."""
    from ...solvers.uncertainty import tracked_provider

    return tracked_provider("learned" if provider_name == "learned" else "oracle-realistic", source)


def _sequences(config: BenchConfig, seed: int, count: int):
    """``(category, provider name, provider, sequence index, [(frame, blank), ...])`` of ``count`` sequences per
    procedural object (frame seed ``seed``; one provider per category and provider name, shared by its sequences)."""
    from ...data.generate import FrameGenerator, GenerationConfig
    from ...data.sequences import SequenceMotion

    for category in config.categories:
        gen = FrameGenerator(GenerationConfig(category=category, split="test", seed=seed,
                                              sequence=SequenceMotion(length=config.length)))
        for provider_name in config.providers:
            provider = _provider(provider_name, category, config)
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
    from ...solvers.types import Observation
    from ..uncertainty_calibration import QUANTITIES, error_records
    from ..uncertainty_calibration import summarize as fit_maps
    from ...tracking.tracker import CategoryTracker, TrackerConfig, TrackStatus

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
    from ..._machine import machine_facts
    from ...solvers.types import Observation
    from ...tracking.tracker import CategoryTracker, TrackerConfig, fit_frame

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
    return {"config": config.to_dict(), "tracker": asdict(tcfg) | {"fit": None if tcfg.fit is None else asdict(tcfg.fit)},
            "machine": {"start": machine_start, "end": machine_facts()}, "records": records}


def _urdf_records(config: BenchConfig, say) -> list:
    from ...data.generate import FrameGenerator, GenerationConfig
    from ...data.sequences import SequenceMotion
    from ...solvers.icp.articulated import articulated_icp, auto_init
    from ..cad import PartPoints
    from ...tracking.instance import InstanceTracker, InstanceTrackerConfig

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


