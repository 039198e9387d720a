"""``ancsh bench uncertainty``: are the fits' standard deviations calibrated? Measure, inflate, report.

For rendered frames of each category, the oracle provider (ground truth corrupted by the
``realistic`` preset, :mod:`ancsh.solvers.providers.oracle`) and the learned provider (the shipped
weights, :class:`~ancsh.learned.inference.provider.LearnedProvider`, with the plausibility checks of
``ancsh predict``) give correspondences; the default fit (``exact_reduced``) reports raw Jacobian
covariances (:mod:`ancsh.solvers.uncertainty`). Each fitted quantity's error against the ground
truth is normalised by its covariance -- a squared Mahalanobis distance ``d^2`` with ``dof``
degrees of freedom:

- ``rotation`` (per part, 3): the camera-frame tangent ``log(R_true R_fit^T)``;
- ``translation`` (per part, 3): ``t_true - t_fit`` of ``T_cam_npcs`` (metres);
- ``scale`` (per part, 1);
- ``joint_state`` (per joint, 1): revolute differences wrapped into ``(-pi, pi]``;
- ``joint_axis`` (per joint, 2): the true unit axis (sign matched) minus the fitted one, in the
  plane perpendicular to the fitted axis;
- ``joint_pivot`` (revolute joints, 2): the true pivot minus the fitted one, perpendicular to the
  fitted axis (the distance of the true axis line, to first order).

The inflation has two measured parts: a within-part residual correlation ``rho`` per provider
and category (:attr:`ancsh.solvers.uncertainty.Inflation.correlation`: a part's ``n`` points count
as ``n / (1 + (n - 1) rho)`` independent ones, since network and warp errors do not average out
over points), chosen from :data:`CORRELATION_GRID`, and per quantity an
:class:`~ancsh.solvers.uncertainty.SigmaMap` of each fit's raw standard deviation (a single factor,
a power about a reference, or a factor with a floor; one map for all parts or joints, or one per
part or joint: :func:`fit_quantity_inflation`, :func:`fit_sigma_map`).

The truth lies "within ``k`` sigma" when ``d^2 <= chi2_dof^-1(P(|z| <= k))`` (68.27 % for ``k = 1``,
95.45 % for ``k = 2``): the one-dimensional ``k``-sigma probability carried to ``dof`` dimensions.
A map with ratio ``f = sigma' / sigma`` divides ``d^2`` by ``f^2``; per provider, category and
quantity the map minimising the larger of the two coverage gaps (and per provider and category
the correlation whose single factors leave the smallest mean gap) is measured on **calibration
frames** (the held-out test instances, frame seed stream ``--calibration-seed``, never the test
frames) and the coverage is then reported on the **test frames** (seed ``--seed``, the frames of
``ancsh evaluate``). Failed fits are counted, not scored; quantities the data left undetermined
(infinite variance) are counted, not scored.

``--install`` writes the maps to ``ancsh/weights/uncertainty_inflation.json``, which
``ancsh predict`` and ``ancsh track`` apply (:func:`ancsh.solvers.uncertainty.inflation_for`).
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from .statistics import QUANTITIES, ErrorRecord, error_records

__all__ = ["CalibrationConfig", "merge_records", "measure", "save_records", "load_records", "PROVIDERS",
           "DEFAULT_PROVIDERS"]

PROVIDERS = ("oracle-realistic", "learned", "learned-template", "learned-network")
#: What runs without ``--providers``: ``learned-template`` (the learned fits refined by the category
#: template, ICP covariances; about half a second more per frame) and ``learned-network`` (refined by the
#: category's refinement network) only when asked for.
DEFAULT_PROVIDERS = ("oracle-realistic", "learned")
#: Default calibration frames per test frame (:attr:`CalibrationConfig.calibration_frames`).
CALIBRATION_FRAMES_PER_TEST_FRAME = 2


def _shipped_categories() -> tuple:
    from ...learned.network.weights import shipped_categories

    return tuple(shipped_categories())


@dataclass(frozen=True)
class CalibrationConfig:
    """What the study runs.

    Attributes
    ----------
    categories : tuple of str
        Default: every category with a shipped ANCSH network
        (:func:`ancsh.learned.network.weights.shipped_categories`), since the maps are installed per category.
    providers : tuple of str
        From :data:`PROVIDERS` (default :data:`DEFAULT_PROVIDERS`). ``learned-template``: the learned
        fits refined against the category template (:meth:`~ancsh.learned.inference.provider.LearnedProvider.refine`,
        forced on), only the frames whose refinement was accepted as the ``articulated`` candidate (the
        others keep the learned fit, which the ``learned`` row calibrates, or carry no covariance: counted
        as ``not_refined``); their covariance is the template ICP's, without a
        scale (chosen by the scale search), so they have no ``scale`` row. ``learned-network``: the learned
        fits refined by the category's shipped refinement network (``refine="network"``, its default passes),
        the frames whose refinement was accepted (the others counted as ``not_refined``); the exact fit's
        covariance on the refiner's correspondences.
    frames : int
        Test frames per category.
    calibration_frames : int or None
        Calibration frames per category; ``None``: :data:`CALIBRATION_FRAMES_PER_TEST_FRAME` times
        ``frames``. A map measured on as few frames as it is tested on carries the calibration
        frames' sampling error into the test coverage on top of the test frames' own (measured:
        laptop / learned / joint state, 150 + 150 frames, one resampled row in 16 missed the target
        by chance; with twice the calibration frames one in 100).
    seed : int
        Base seed of the test frames (``ancsh evaluate``'s stream).
    calibration_seed : int
        Base seed of the calibration frames (another stream of the held-out instances).
    formulation : str
    """

    categories: tuple = field(default_factory=lambda: _shipped_categories())
    providers: tuple = DEFAULT_PROVIDERS
    frames: int = 150
    calibration_frames: int | None = None
    seed: int = 0
    calibration_seed: int = 1001
    formulation: str = "exact_reduced"

    def __post_init__(self):
        unknown = [p for p in self.providers if p not in PROVIDERS]
        if unknown:
            raise ValueError(f"providers: unknown {unknown}; known: {list(PROVIDERS)}")
        for name in ("frames", "calibration_frames"):
            v = getattr(self, name)
            if v is None and name == "calibration_frames":
                continue
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 4:
                raise ValueError(f"{name}: expected an integer >= 4, got {v!r}")

    @property
    def n_calibration(self) -> int:
        """Calibration frames per category (:attr:`calibration_frames` or its default)."""
        return int(self.calibration_frames if self.calibration_frames is not None
                   else CALIBRATION_FRAMES_PER_TEST_FRAME * self.frames)
        if self.seed == self.calibration_seed:
            raise ValueError("calibration_seed: must differ from seed (calibration frames are never test frames)")


# ------------------------------------------------------------------------------------------------
# measuring
# ------------------------------------------------------------------------------------------------
def measure(config: CalibrationConfig, *, progress=None) -> dict:
    """Normalised errors of every (category, provider, split) and the fits' costs.

    Returns
    -------
    dict
        ``{"records": {category: {provider: {split: {quantity: [(e, C, C_corr), ...]}}}}, "counts": ...,
        "timing": {provider: {"fit_ms": [...], "fit_ms_without": [...], "covariance_ms": [...]}}}``.
    """
    from ...data.generate import FrameGenerator, GenerationConfig
    from ...solvers import FitConfig, Observation, fit
    from ..fit.measure import _limits  # joint limits relative to rest, as the fit benchmark passes them
    from ...solvers.providers.oracle import OracleProvider

    records, counts = {}, {}
    timing = {p: {"fit_ms": [], "fit_ms_without": [], "covariance_ms": []} for p in config.providers}
    for cat in config.categories:
        learned = None
        if {"learned", "learned-template", "learned-network"} & set(config.providers):
            from ...learned.inference.provider import LearnedProvider

            learned = LearnedProvider(cat, seed=config.seed, num_threads=1,
                                      refine="network" if "learned-network" in config.providers else None)
        records[cat] = {p: {} for p in config.providers}
        counts[cat] = {p: {} for p in config.providers}
        for split, seed, n_frames in (("calibration", config.calibration_seed, config.n_calibration),
                                      ("test", config.seed, config.frames)):
            gen = FrameGenerator(GenerationConfig(category=cat, split="test", seed=seed))
            for p in config.providers:
                records[cat][p][split] = {q: [] for q in QUANTITIES}
                counts[cat][p][split] = {"frames": 0, "failed": 0, "singular": 0}
                if p in ("learned-template", "learned-network"):
                    counts[cat][p][split]["not_refined"] = 0
            t0 = time.perf_counter()
            for i in range(n_frames):
                frame = gen.frame(i)
                model, _ = gen.instance(frame.instance_index)
                obs = Observation(frame.points)
                inferred = None  # the network's output, shared by the learned providers of this frame
                for p in config.providers:
                    rng = np.random.default_rng([seed, i, 17])
                    if p.startswith("learned"):
                        from ...learned.inference.predict import check_plausibility, infer, part_quality

                        inferred = infer(learned, obs) if inferred is None else inferred
                        corr, raw = inferred
                    else:
                        corr = OracleProvider(frame.gt, p.split("-", 1)[1], rng, joint_limits=_limits(model)).correspond(obs)
                    fit_config = learned.fit_config() if p.startswith("learned") else FitConfig()  # the default objective
                    result = fit(obs, corr, config.formulation, config=fit_config, rng=i)
                    if p in ("learned-template", "learned-network") and result.ok:
                        from ...learned.inference.provider import apply_refinement

                        refined = apply_refinement(learned, obs, corr, raw, result, refine=p.split("-", 1)[1], rng=i)
                        if refined.kind is None or refined.result.uncertainty is None:  # kept the input, or base
                            counts[cat][p][split]["not_refined"] += 1
                            continue
                        result, corr, raw = refined.result, refined.correspondences, refined.prediction
                    if p.startswith("learned"):
                        result = check_plausibility(result, corr.part_labels, learned.category_info.convention, part_quality(result, frame.points, corr, raw))
                    if split == "test":
                        ref = fit(obs, corr, config.formulation, config=replace(fit_config, uncertainty=False), rng=i)
                        timing[p]["fit_ms"].append(1e3 * result.time_s)
                        timing[p]["fit_ms_without"].append(1e3 * ref.time_s)
                        if result.uncertainty is not None:
                            timing[p]["covariance_ms"].append(1e3 * result.uncertainty.time_s)
                    c = counts[cat][p][split]
                    c["frames"] += 1
                    if not result.ok or result.uncertainty is None:
                        c["failed"] += 1
                        continue
                    if result.uncertainty.status != "ok":
                        c["singular"] += 1
                    with np.errstate(invalid="ignore"):  # an unbounded (inf) variance makes nan records, left out
                        per_quantity = error_records(result, frame.gt)
                    for q, v in per_quantity.items():
                        if p == "learned-template" and q == "scale":
                            continue  # not estimated: chosen by the scale search (variance nan)
                        records[cat][p][split][q] += v
            if progress is not None:
                progress(f"{cat} {split}: {n_frames} frames in {time.perf_counter() - t0:.0f} s")
    return {"records": records, "counts": counts, "timing": timing}


_RECORD_FIELDS = ("error", "covariance", "correlated", "variance", "correlated_variance", "index")


def save_records(measured: dict, path) -> Path:
    """Write :func:`measure`'s output to ``path`` (``.npz``: per category, provider, split and quantity the
    arrays of its :class:`ErrorRecord` fields; counts and timing as JSON), so that inflation maps can be
    compared without fitting the frames again (:func:`load_records`)."""
    arrays = {"meta": np.array(json.dumps({"counts": measured["counts"], "timing": measured["timing"],
                                           "source": measured.get("source")}))}
    for cat, per in measured["records"].items():
        for p, splits in per.items():
            for split, qs in splits.items():
                for q, recs in qs.items():
                    dof = QUANTITIES[q]
                    for f in _RECORD_FIELDS:
                        shape = {"error": (0, dof), "covariance": (0, dof, dof), "correlated": (0, dof, dof)}.get(f, (0,))
                        v = np.array([getattr(r, f) for r in recs]) if recs else np.zeros(shape)
                        arrays[f"{cat}/{p}/{split}/{q}/{f}"] = v
    import io

    from ...outputs import write_bytes_atomically

    path, buffer = Path(path), io.BytesIO()
    np.savez_compressed(buffer, **arrays)
    write_bytes_atomically(path, buffer.getvalue())
    return path


def load_records(path) -> dict:
    """:func:`measure`'s output from :func:`save_records`' file.

    Raises
    ------
    ValueError
        When ``path`` is missing or not such a file (naming it).
    """
    try:
        data = np.load(Path(path), allow_pickle=False)
        meta = json.loads(str(data["meta"]))
    except (OSError, KeyError, ValueError) as exc:
        raise ValueError(f"{path}: not a records file of ancsh bench uncertainty --save-records ({exc})") from exc
    records = {}
    for key in data.files:
        if key == "meta" or not key.endswith("/index"):
            continue
        cat, p, split, q, _ = key.split("/")
        cols = [data[f"{cat}/{p}/{split}/{q}/{f}"] for f in _RECORD_FIELDS]
        recs = [ErrorRecord(cols[0][i], cols[1][i], cols[2][i], float(cols[3][i]), float(cols[4][i]), int(cols[5][i]))
                for i in range(len(cols[5]))]
        records.setdefault(cat, {}).setdefault(p, {}).setdefault(split, {})[q] = recs
    out = {"records": records, "counts": meta["counts"], "timing": meta["timing"]}
    if meta.get("source"):
        out["source"] = meta["source"]  # the command that fitted the frames, and its time
    return out


def merge_records(parts: list) -> dict:
    """One :func:`measure` output from several (:func:`load_records` of files measured separately).

    Categories are independent in the study (their own frames, correlation and maps), so the runs of
    different categories combine; a category held by several parts is taken from the last one (a
    category re-measured, e.g. for new weights). Counts follow the records; the fit timings (per
    provider, not per category) are pooled over every part's frames, a replaced category's included.
    ``source`` lists each part's command.
    """
    if not parts:
        raise ValueError("parts: expected at least one measured set")
    records, counts, timing, sources = {}, {}, {}, []
    for m in parts:
        records.update(m["records"])
        counts.update(m["counts"])
        for prov, t in m["timing"].items():
            for key, v in t.items():
                timing.setdefault(prov, {}).setdefault(key, []).extend(v)
        src = m.get("source")
        sources += src if isinstance(src, list) else [src] if src else []
    out = {"records": records, "counts": counts, "timing": timing}
    if sources:
        out["source"] = sources[0] if len(sources) == 1 else sources
    return out


