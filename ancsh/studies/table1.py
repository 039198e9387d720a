"""``ancsh evaluate``: the paper's Table 1 / Table 2 and the occlusion analysis on held-out instances.

Frames are rendered on the fly (:class:`~ancsh.data.generate.FrameGenerator`, ``split="test"``:
instances never seen in training, Kinect-like depth noise, 1024 points). Every frame goes once
through the shipped ANCSH network (:class:`~ancsh.learned.inference.provider.LearnedProvider`); the methods
then fit the same network output, so they differ only in how they use it:

``per_part`` (NPCS baseline)
    Per-part Umeyama + RANSAC on the predicted NPCS (no joint constraints), ``FitConfig.paper()``.
``naocs`` (NAOCS baseline)
    Per-part poses fitted from the predicted NAOCS ``G_s,i * NPCS_i + G_t,i`` with the network's
    *per-point* scale and translation (:func:`naocs_correspondences`: the NAOCS coordinates play the
    role of NPCS with identity NPCS -> NAOCS maps, ``per_part`` formulation). With the provider's
    per-part (median) ``G_s, G_t`` instead, NAOCS would be a similarity transform of NPCS per part and
    the baseline would equal the NPCS one exactly. The fitted NAOCS -> camera pose of each part is
    reported as an NPCS -> camera pose by composing it with the provider's per-part ``(G_s, G_t)``,
    so the same Table-1 metrics apply. No amodal boxes (as in the paper).
``soft`` (ANCSH, the paper's combined optimisation)
    Sec. 4.3 soft joint energies, ``FitConfig.paper()``.
``exact_reduced`` / ``exact_maximal`` (ANCSH-exact, ours)
    Joints as exact constraints (IPOPT), default ``FitConfig()``.
``template`` (ANCSH-exact + category template, ours; only when asked for, ``refine="template"``)
    The ``exact_reduced`` fit refined by articulated ICP against the nearest training instance of the
    category (:func:`ancsh.solvers.icp.category.refine_fit`): kept only where its own score on the
    observed points beats the input fit's, else the ``exact_reduced`` fit itself.

The NPCS and NAOCS baselines use the heads of the one ANCSH network rather than separately trained
networks. Frame metrics come from :func:`ancsh.evaluation.evaluate_fit` (one definition).
Statistics are means over frames -- the paper's official evaluation script averages per part --
with medians beside them; failed fits are left out and counted.
"""

from __future__ import annotations

from ..learned.network.weights import missing_weights_error

from ..outputs import json_safe

import dataclasses
import datetime
import json
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._machine import describe_machine, machine_facts
from ..solvers.types import Correspondences, FitResult, Observation
from ..data.procedural import GENERATOR_VERSION
from ..learned.network.weights import shipped_categories  # noqa: F401  (re-exported: the evaluation's category list)

__all__ = [
    "DEFAULT_METHODS",
    "METHODS",
    "PAPER_TABLE1",
    "PAPER_TABLE2",
    "Method",
    "TIMING_KEYS",
    "evaluate_category",
    "fit_method",
    "fit_naocs",
    "json_safe",
    "naocs_correspondences",
    "missing_weights_error",
    "npcs_error_budget",
    "per_point_naocs",
    "shipped_categories",
    "summarize",
    "write_json",
    "write_real_report",
    "write_report",
]


@dataclass(frozen=True)
class Method:
    """One row of Table 1: a label, the fitting formulation, and whether it uses the paper's config."""

    key: str
    label: str
    formulation: str
    paper_config: bool


METHODS: dict[str, Method] = {
    m.key: m
    for m in (
        Method("per_part", "NPCS (per part)", "per_part", True),
        Method("naocs", "NAOCS", "per_part", True),
        Method("soft", "ANCSH-soft (paper)", "soft", True),
        Method("exact_reduced", "ANCSH-exact reduced (ours)", "exact_reduced", False),
        Method("exact_maximal", "ANCSH-exact maximal (ours)", "exact_maximal", False),
        Method("template", "ANCSH-exact + category template (ours)", "exact_reduced", False),
    )
}
"""Methods of Table 1 by key (``--formulations`` takes these keys)."""

DEFAULT_METHODS = tuple(k for k in METHODS if k != "template")
"""The methods evaluated by default (the template refinement costs far more per frame: asked for with ``refine``)."""

# The paper's Table 1 (means over ~3000 test images of unseen instances of its CAD datasets; translation
# and line distance in object units, joint states in degrees or object units for drawers).
PAPER_TABLE1 = {
    "eyeglasses": {
        "NPCS": dict(rot_deg=[4.0, 7.7, 7.2], trans=[0.044, 0.080, 0.071], iou=[86.9, 40.5, 41.4], state_err=[8.8, 8.4]),
        "NAOCS": dict(rot_deg=[4.2, 12.1, 13.5], trans=[0.157, 0.252, 0.168], state_err=[13.7, 15.1]),
        "ANCSH": dict(rot_deg=[3.7, 5.1, 3.7], trans=[0.035, 0.051, 0.057], iou=[87.4, 43.6, 44.5], state_err=[4.3, 4.5],
                      axis_deg=[2.2, 2.3], line_dist=[0.019, 0.014]),
    },
    "oven": {
        "NPCS": dict(rot_deg=[1.3, 3.5], trans=[0.032, 0.049], iou=[75.8, 88.5], state_err=[4.0]),
        "NAOCS": dict(rot_deg=[1.7, 4.7], trans=[0.036, 0.090], state_err=[5.1]),
        "ANCSH": dict(rot_deg=[1.1, 2.2], trans=[0.030, 0.046], iou=[75.9, 89.0], state_err=[2.1], axis_deg=[0.8],
                      line_dist=[0.024]),
    },
    "washing_machine": {
        "NPCS": dict(rot_deg=[1.1, 2.0], trans=[0.043, 0.056], iou=[86.9, 88.0], state_err=[2.3]),
        "NAOCS": dict(rot_deg=[1.1, 3.3], trans=[0.072, 0.119], state_err=[3.1]),
        "ANCSH": dict(rot_deg=[1.0, 1.4], trans=[0.042, 0.053], iou=[87.0, 88.3], state_err=[1.0], axis_deg=[0.7],
                      line_dist=[0.008]),
    },
    "laptop": {
        "NPCS": dict(rot_deg=[11.6, 4.4], trans=[0.098, 0.044], iou=[35.7, 93.6], state_err=[14.4]),
        "NAOCS": dict(rot_deg=[12.4, 4.9], trans=[0.110, 0.049], state_err=[15.2]),
        "ANCSH": dict(rot_deg=[6.7, 4.3], trans=[0.062, 0.044], iou=[41.1, 93.0], state_err=[9.7], axis_deg=[0.5],
                      line_dist=[0.017]),
    },
    "drawer": {
        "NPCS": dict(rot_deg=[1.9, 3.5, 2.4, 1.8], trans=[0.032, 0.038, 0.024, 0.025], iou=[82.8, 71.2, 71.5, 79.3],
                     state_err=[0.026, 0.031, 0.046]),
        "NAOCS": dict(rot_deg=[1.5, 2.5, 2.5, 2.0], trans=[0.044, 0.045, 0.073, 0.054], state_err=[0.043, 0.066, 0.048]),
        "ANCSH": dict(rot_deg=[1.0, 1.1, 1.2, 1.5], trans=[0.024, 0.021, 0.021, 0.033], iou=[84.0, 72.1, 71.7, 78.6],
                      state_err=[0.011, 0.020, 0.030], axis_deg=[0.8, 0.8, 0.8]),
    },
}
"""The paper's Table 1 by category and method (``NPCS``, ``NAOCS``, ``ANCSH``)."""

# The paper's Table 2: direct joint voting (PointNet++) vs ANCSH, camera-space joint parameters.
PAPER_TABLE2 = {
    "eyeglasses": {"direct_voting": dict(axis_deg=[2.9, 15.7], line_dist=[0.140, 0.197]),
                   "ANCSH": dict(axis_deg=[2.2, 2.3], line_dist=[0.019, 0.014])},
    "oven": {"direct_voting": dict(axis_deg=[27.0], line_dist=[0.024]), "ANCSH": dict(axis_deg=[0.8], line_dist=[0.024])},
    "washing_machine": {"direct_voting": dict(axis_deg=[8.7], line_dist=[0.010]),
                        "ANCSH": dict(axis_deg=[0.7], line_dist=[0.008])},
    "laptop": {"direct_voting": dict(axis_deg=[29.5], line_dist=[0.007]), "ANCSH": dict(axis_deg=[0.5], line_dist=[0.017])},
    "drawer": {"direct_voting": dict(axis_deg=[4.9, 5.0, 5.1]), "ANCSH": dict(axis_deg=[0.8, 0.8, 0.8])},
}
"""The paper's Table 2 by category (``direct_voting`` = its PointNet++ baseline, ``ANCSH``)."""

PART_METRICS = ("rot_deg", "trans", "iou", "iou_pose", "scale_rel")
JOINT_METRICS = ("state_err", "axis_deg", "line_dist")
BUDGET_METRICS = ("npcs_err", "npcs_rot_deg", "npcs_resid")


# --------------------------------------------------------------------------------------------
# the NAOCS baseline
# --------------------------------------------------------------------------------------------
def naocs_correspondences(corr: Correspondences, naocs=None) -> Correspondences:
    """The NAOCS baseline's input: each point's NAOCS coordinates used as its "NPCS".

    Parameters
    ----------
    corr : Correspondences
    naocs : (N, 3) float64, optional
        Per-point NAOCS (e.g. from the network's per-point ``G_s, G_t``); default
        ``G_s[l] * npcs + G_t[l]`` with the per-part maps of ``corr``.

    The NPCS -> NAOCS maps become identities (scale 1, translation 0), so a fit returns each part's
    NAOCS -> camera pose; joints, labels and weights are kept. No amodal extents.
    """
    from ..geometry._checks import as_array

    if not isinstance(corr, Correspondences):
        raise ValueError(f"corr: expected Correspondences, got {type(corr).__name__}")
    lab = corr.part_labels
    if naocs is None:
        naocs = corr.npcs_scale[lab, None] * corr.npcs + corr.npcs_translation[lab]
    else:
        naocs = as_array(naocs, "naocs", (corr.num_points, 3))
    M = corr.num_parts
    return Correspondences(
        part_labels=lab, npcs=naocs, npcs_scale=np.ones(M), npcs_translation=np.zeros((M, 3)),
        joint_types=corr.joint_types, joint_parents=corr.joint_parents, joint_children=corr.joint_children,
        joint_axes_naocs=corr.joint_axes_naocs, joint_pivots_naocs=corr.joint_pivots_naocs,
        weights=corr.weights, joint_limits=corr.joint_limits,
    )


def fit_naocs(observation: Observation, corr: Correspondences, *, naocs=None, config=None, rng=0) -> FitResult:
    """The NAOCS baseline: per-part fits of the predicted NAOCS (see the module docstring).

    Returns a :class:`FitResult` whose ``T_cam_npcs[j]`` is the fitted NAOCS -> camera pose of part
    ``j`` composed with the predicted NPCS -> NAOCS map ``(G_s[j], G_t[j])`` (rotation unchanged),
    with no boxes and formulation ``"naocs"``. ``naocs`` as in :func:`naocs_correspondences`.
    """
    from ..geometry.transforms import Sim3
    from ..solvers import fit

    r = fit(observation, naocs_correspondences(corr, naocs), "per_part", config=config, rng=rng)
    poses = tuple(
        T @ Sim3(np.eye(3), corr.npcs_translation[j], float(corr.npcs_scale[j])) for j, T in enumerate(r.T_cam_npcs)
    )
    return dataclasses.replace(r, formulation="naocs", T_cam_npcs=poses, boxes_cam=())


def per_point_naocs(prediction, corr: Correspondences) -> np.ndarray:
    """``(N, 3)`` NAOCS from the network's per-point scale and translation of each point's chosen part."""
    rows = np.arange(corr.num_points)
    lab = corr.part_labels
    return prediction.scale[rows, lab, None] * corr.npcs + prediction.translation[rows, lab]


def fit_method(key: str, observation: Observation, corr: Correspondences, *, naocs=None, rng=0) -> FitResult:
    """Fit one :data:`METHODS` entry to the network's correspondences (``naocs``: per-point NAOCS for ``"naocs"``)."""
    from ..solvers import FitConfig, fit

    if key not in METHODS:
        raise ValueError(f"key: expected one of {list(METHODS)}, got {key!r}")
    if key == "template":
        raise ValueError("key: 'template' refines an exact_reduced fit; use ancsh.solvers.icp.category.refine_fit")
    m = METHODS[key]
    config = FitConfig.paper() if m.paper_config else FitConfig()
    if key == "naocs":
        return fit_naocs(observation, corr, naocs=naocs, config=config, rng=rng)
    return fit(observation, corr, m.formulation, config=config, rng=rng)


# --------------------------------------------------------------------------------------------
# the evaluation loop
# --------------------------------------------------------------------------------------------
def _direct_joint_errors(axes, pivots, gt) -> list[dict]:
    from ..geometry.metrics import axis_angle_error_deg, line_distance

    L = float(gt.T_cam_naocs.scale)
    out = []
    for k in range(gt.num_joints):
        revolute = gt.joint_types[k].value == "revolute"
        out.append({
            "axis_deg": axis_angle_error_deg(axes[k], gt.joint_axes_cam[k]),
            "line_dist": line_distance(pivots[k], axes[k], gt.joint_pivots_cam[k], gt.joint_axes_cam[k]) / L
            if revolute else float("nan"),
        })
    return out


def _naocs_joint_errors(corr: Correspondences, gt) -> list[dict]:
    """Errors of the network's voted joints in NAOCS (before any fit): axis angle, line distance (object units)."""
    from ..geometry.metrics import axis_angle_error_deg, line_distance

    out = []
    for k in range(gt.num_joints):
        u, p = corr.joint_axes_naocs[k], corr.joint_pivots_naocs[k]
        revolute = gt.joint_types[k].value == "revolute"
        out.append({
            "axis_deg": axis_angle_error_deg(u, gt.joint_axes_naocs[k]),
            "line_dist": line_distance(p, u, gt.joint_pivots_naocs[k], gt.joint_axes_naocs[k]) if revolute else float("nan"),
        })
    return out


def npcs_error_budget(prediction, gt) -> dict:
    """Where a frame's rotation error comes from: the network's NPCS head against the ground truth.

    For each part ``j``, on the points that truly belong to it (ground-truth labels, so
    segmentation errors are left out), the NPCS the network predicts *for part j* are compared
    with the true NPCS. The true NPCS are an exact similarity transform of the observed camera
    points, so a similarity fitted from the predicted onto the true NPCS splits the error into

    ``npcs_rot_deg``
        the rotation of that similarity (degrees): the orientation error the predicted NPCS
        carry. It *equals* the rotation error of an Umeyama fit of the predicted NPCS to the
        observed points (no RANSAC, true labels): no fitting method can remove it from one part.
    ``npcs_resid``
        the mean distance left after that similarity (NPCS units): the non-rigid part of the error.
    ``npcs_err``
        the raw mean distance between predicted and true NPCS (NPCS units).

    Parameters
    ----------
    prediction : Prediction
        Raw network output for the frame's ``N`` points (``npcs`` ``(N, M, 3)``).
    gt : AncshGroundTruth
        The frame's ground truth (``part_labels``, ``npcs``).

    Returns
    -------
    dict
        ``parts``: one dict per part with the three numbers (NaN for a part with fewer than 4 points),
        ``seg_acc``: fraction of points whose most likely part is the true one.
    """
    from ..geometry import umeyama
    from ..geometry.rotations import rotation_angle

    parts = []
    for j in range(prediction.npcs.shape[1]):
        m = gt.part_labels == j
        row = {"npcs_rot_deg": np.nan, "npcs_resid": np.nan, "npcs_err": np.nan}
        if m.sum() >= 4:
            pred, true = prediction.npcs[m, j], gt.npcs[m]
            row["npcs_err"] = float(np.linalg.norm(pred - true, axis=1).mean())
            try:
                T = umeyama(pred, true)
            except ValueError:  # degenerate prediction: no orientation to measure
                pass
            else:
                row["npcs_rot_deg"] = float(np.degrees(rotation_angle(T.rotation)))
                row["npcs_resid"] = float(np.linalg.norm(T.apply(pred) - true, axis=1).mean())
        parts.append(row)
    seg_acc = float(np.mean(prediction.seg_prob.argmax(1) == gt.part_labels))
    return {"parts": parts, "seg_acc": seg_acc}


class _FrameEvaluator:
    """A worker of :func:`evaluate_category`: renders test frame ``i``, runs the networks once and fits every
    method; ``worker(i)`` returns the frame's record (a pure function of the settings and ``i``)."""

    def __init__(self, category: str, seed: int, real, weights: str, direct_weights, num_threads: int, methods: tuple,
                 device="cpu", instances: str = "test"):
        from ..data.generate import FrameGenerator, GenerationConfig
        from ..learned.inference.provider import DirectVotingPredictor, LearnedProvider

        cfg = dict(category=category, split=instances, seed=int(seed))
        if real is not None:
            cfg.update(real=real, real_fraction=1.0)
        self.generator = FrameGenerator(GenerationConfig(**cfg))
        self.provider = LearnedProvider(weights, seed=seed, num_threads=num_threads, device=device)
        self.voter = None if direct_weights is None else DirectVotingPredictor(direct_weights, seed=seed, device=device)
        self.seed, self.methods = int(seed), tuple(methods)
        self.library = None
        if "template" in self.methods:
            from ..data.templates import load_template_library

            self.library = load_template_library(category)

    def __call__(self, i: int) -> dict:
        from ..evaluation import evaluate_fit

        t0 = time.perf_counter()
        fr = self.generator.frame(i)
        t_gen = time.perf_counter() - t0
        self.provider.check_structure(fr.part_names, fr.gt.joint_types, where=f"test instance {fr.instance!r}")
        obs = Observation(fr.points)
        t0 = time.perf_counter()
        inference = self.provider.infer(obs)
        corr = inference.correspondences
        t_net = time.perf_counter() - t0
        naocs = per_point_naocs(inference.prediction, corr)
        rec = {
            "frame": i, "instance": fr.instance, "visibility": fr.visibility.tolist(),
            "generate_ms": 1e3 * t_gen, "network_ms": 1e3 * t_net, "methods": {},
            "naocs_joints": _naocs_joint_errors(corr, fr.gt),
            "budget": npcs_error_budget(inference.prediction, fr.gt),
        }
        fits = {}
        for key in self.methods:
            if key == "template":
                continue
            r = fits[key] = fit_method(key, obs, corr, naocs=naocs, rng=self.seed + i)
            ev = evaluate_fit(r, fr.gt, fr.part_names, fr.joint_names).to_dict()
            ev["fit_ms"] = 1e3 * r.time_s
            rec["methods"][key] = ev
        if self.library is not None:
            from ..solvers.icp.category import refine_fit

            base = fits["exact_reduced"] if "exact_reduced" in fits else fit_method("exact_reduced", obs, corr, rng=self.seed + i)
            ref = refine_fit(obs, base, corr, self.library, rng=self.seed + i)
            ev = evaluate_fit(ref.result, fr.gt, fr.part_names, fr.joint_names).to_dict()
            ev["fit_ms"] = 1e3 * ref.result.time_s if ref.accepted else 1e3 * (base.time_s + ref.time_s)
            ev["refine"] = {"accepted": ref.accepted, "choice": ref.choice, "scale": ref.scale, "template": ref.template,
                            "refine_ms": 1e3 * ref.time_s, "score_input": ref.score_input,
                            "score_refined": ref.score_refined}
            rec["methods"]["template"] = ev
        if self.voter is not None:
            t0 = time.perf_counter()
            axes, pivots, _ = self.voter.joints(obs)
            rec["direct_voting"] = {"joints": _direct_joint_errors(axes, pivots, fr.gt),
                                    "network_ms": 1e3 * (time.perf_counter() - t0)}
        return rec


TIMING_KEYS = ("generate_ms", "network_ms", "fit_ms", "wall_s", "direct_voting_network_ms", "refine_ms")
"""Keys of :func:`evaluate_category` records and :func:`summarize` output that hold measured times: everything
else is a function of the settings alone (the same on any executor, with any number of workers)."""


def evaluate_category(
    category: str,
    *,
    frames: int = 100,
    methods=DEFAULT_METHODS,
    seed: int = 0,
    weights=None,
    direct_weights=None,
    time_limit_s: float | None = None,
    num_threads: int = 1,
    progress: bool = True,
    real: str | None = None,
    refine: str | None = None,
    executor=None,
    device="cpu",
    instances: str = "test",
) -> dict:
    """Run the network and every method on ``frames`` rendered test frames of ``category``.

    Parameters
    ----------
    category : str
        Procedural category (its held-out test instances are rendered).
    frames : int
        Frames ``0..frames-1`` of the test stream with base seed ``seed``.
    methods : sequence of str
        Keys of :data:`METHODS`.
    weights : str or Path, optional
        ANCSH weights file (default: the category's shipped weights).
    direct_weights : str or Path, optional
        Direct-voting weights (default: the category's shipped ones if any, else Table 2 is skipped).
    time_limit_s : float, optional
        Stop after this many seconds (the frames done so far are kept).
    num_threads : int
        torch threads (per worker).
    real : str, optional
        A catalog of imported real objects (``"builtin"`` = the shipped one): render its *test*
        objects of ``category`` instead of the procedural test instances (the real test split).
    refine : str, optional
        ``"template"``: add the ``template`` method (the ``exact_reduced`` fit refined against the
        category's template library, :func:`ancsh.data.templates.load_template_library`).
    executor : LocalExecutor or RayExecutor, optional
        Where the frames are evaluated (:mod:`ancsh.executors`; default: in this process). Every
        frame is a pure function of the settings and its index, so the records -- all but the
        :data:`TIMING_KEYS` -- do not depend on it.
    device : str or torch.device
        Where the networks run (``"cpu"``, ``"cuda"``, ``"auto"``); the CPU on Ray workers.
    instances : {"test", "train"}
        Whose frames are rendered: the held-out test instances (default: every report of the project), or
        the *training* instances (new views of the objects the networks were trained on -- about 10 % of
        them were a training run's validation instances -- to measure the gap between them and unseen ones).

    Returns
    -------
    dict
        ``records`` (per frame, in frame order), ``settings`` (``split`` is ``"procedural"`` or
        ``"real"``, ``instances`` ``"test"`` or ``"train"``), ``timing``.

    Raises
    ------
    FileNotFoundError
        When no weights are shipped for ``category`` (the message lists the available ones).
    """
    from ..data.generate import FrameGenerator, GenerationConfig
    from ..executors import LocalExecutor, RayExecutor
    from ..learned.devices import resolve_device
    from ..learned.network.weights import available_weights, load_network, weights_path

    methods = tuple(methods)
    if refine not in (None, "template"):
        raise ValueError(f"refine: expected None or 'template', got {refine!r}")
    if refine == "template" and "template" not in methods:
        methods = methods + ("template",)
    bad = [m for m in methods if m not in METHODS]
    if bad or not methods:
        raise ValueError(f"methods: expected keys of {list(METHODS)}, got {list(methods)}")
    if isinstance(frames, bool) or int(frames) != frames or frames < 1:
        raise ValueError(f"frames: expected a positive integer, got {frames!r}")
    if instances not in ("test", "train"):
        raise ValueError(f"instances: expected 'test' or 'train', got {instances!r}")
    if executor is None:
        executor = LocalExecutor(1)
    elif not isinstance(executor, (LocalExecutor, RayExecutor)):
        raise ValueError(f"executor: expected a LocalExecutor or RayExecutor, got {type(executor).__name__}")
    if executor.kind == "ray":  # Ray workers reserve CPUs only
        if device != "auto" and resolve_device(device).type != "cpu":
            raise ValueError(f"device: the Ray workers reserve CPUs only; run the networks on the cpu (or auto) with "
                             f"the ray executor, got {device!r}")
        device = "cpu"
    device = str(resolve_device(device))
    if real is None:
        gen = FrameGenerator(GenerationConfig(category=category, split=instances, seed=int(seed)))
    else:
        gen = FrameGenerator(GenerationConfig(category=category, split=instances, seed=int(seed), real=real,
                                              real_fraction=1.0))
        if not gen.real_instances:
            raise ValueError(f"real: the catalog {real!r} has no real {instances} object of {category!r}")
    if weights is None and not weights_path(category).is_file():
        raise missing_weights_error(category)
    network = load_network(category if weights is None else weights)  # its file and SHA-256 at load time
    if network.kind != "ancsh":
        raise ValueError(f"weights: expected an ANCSH network, got a {network.kind!r} network")
    direct = None
    if direct_weights is not None:
        direct = str(load_network(direct_weights, kind="direct_voting").source)
    elif weights_path(category, "direct_voting").is_file():
        direct = str(weights_path(category, "direct_voting"))

    records = []
    start = time.perf_counter()
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=int(frames), desc=f"evaluate {category}", unit="frame")
    worker_args = (category, int(seed), real, network.source, direct, int(num_threads), methods, device, instances)
    results = executor.imap(_FrameEvaluator, worker_args, range(int(frames)))
    try:
        for rec in results:
            records.append(rec)
            if bar is not None:
                bar.update(1)
            if time_limit_s is not None and time.perf_counter() - start > time_limit_s:
                break
    finally:
        results.close()  # stops the workers (frames not started are not evaluated)
        if bar is not None:
            bar.close()
    fr0 = gen.frame(0)
    return {
        "category": category,
        "records": records,
        "settings": {
            "frames_requested": int(frames), "frames": len(records), "seed": int(seed), "methods": list(methods),
            "weights": network.source, "weights_step": network.step,
            "weights_sha256": network.sha256,
            "direct_weights": direct,
            "available_weights": available_weights(), "num_threads": int(num_threads), "machine": machine_facts(),
            "test_instances": len(gen.real_instances) if real is not None else gen.num_instances,
            "split": "procedural" if real is None else "real", "instances": instances, "real_catalog": real,
            "real_instances": [o.name for o in gen.real_instances] if real is not None else [],
            "num_points": gen.config.num_points, "generator_version": GENERATOR_VERSION,
            "part_names": list(fr0.part_names), "joint_names": list(fr0.joint_names),
            "joint_types": [t.value for t in fr0.gt.joint_types],
            "time_limit_s": time_limit_s, "refine": refine,
            "executor": executor.describe(), "device": device,
        },
        "timing": {"wall_s": time.perf_counter() - start},
    }


# --------------------------------------------------------------------------------------------
# statistics
# --------------------------------------------------------------------------------------------
def _stats(values: np.ndarray) -> dict:
    """Mean / median over frames per column (:func:`ancsh.evaluation.aggregate`: NaN entries left
    out; ``None`` where a column has no finite entry)."""
    from ..evaluation import aggregate

    out = {"mean": [], "median": []}
    for col in np.asarray(values, dtype=float).T:
        a = aggregate(col).to_dict()
        out["mean"].append(a["mean"])
        out["median"].append(a["median"])
    return out


def summarize(evaluation: dict) -> dict:
    """Means and medians per method, part and joint; Table 2 rows; timings; occlusion bins."""
    recs = evaluation["records"]
    s = evaluation["settings"]
    M, K = len(s["part_names"]), len(s["joint_names"])
    out = {"methods": {}, "table2": {}, "timing": {}}
    for key in s["methods"]:
        ok = [r["methods"][key] for r in recs if r["methods"][key]["ok"]]
        row = {"frames": len(recs), "failures": len(recs) - len(ok)}
        for name in PART_METRICS:
            vals = np.array([[p.get(name, np.nan) for p in e["parts"]] for e in ok]).reshape(-1, M)
            if name.startswith("iou"):
                vals = 100.0 * vals
            row[name] = _stats(vals)
        for name in JOINT_METRICS:
            row[name] = _stats(np.array([[j[name] for j in e["joints"]] for e in ok]).reshape(-1, K))
        fit_ms = [r["methods"][key]["fit_ms"] for r in recs]
        row["fit_ms"] = {"mean": float(np.mean(fit_ms)), "median": float(np.median(fit_ms))} if fit_ms else None
        refs = [r["methods"][key]["refine"] for r in recs if "refine" in r["methods"][key]]
        if refs:
            choices = [x["choice"] for x in refs]
            ms = [x["refine_ms"] for x in refs]
            row["refine"] = {
                "frames": len(refs), "accepted": int(sum(x["accepted"] for x in refs)),
                "choices": {c: choices.count(c) for c in ("input", "articulated", "base")},
                "scales": {str(sc): sum(1 for x in refs if x["accepted"] and x["scale"] == sc)
                           for sc in sorted({x["scale"] for x in refs if x["accepted"]})},
                "refine_ms": {"mean": float(np.mean(ms)), "median": float(np.median(ms))},
            }
        out["methods"][key] = row
    nj = [r["naocs_joints"] for r in recs if "naocs_joints" in r]
    if nj:
        out["table2"]["naocs_vote"] = {
            name: _stats(np.array([[j[name] for j in d] for d in nj]).reshape(-1, K)) for name in ("axis_deg", "line_dist")
        }
    bud = [r["budget"] for r in recs if "budget" in r]
    if bud:
        out["budget"] = {
            name: _stats(np.array([[p[name] for p in b["parts"]] for b in bud]).reshape(-1, M)) for name in BUDGET_METRICS
        }
        out["budget"]["seg_acc"] = _stats(np.array([[b["seg_acc"]] for b in bud]))
    dv = [r["direct_voting"] for r in recs if "direct_voting" in r]
    if dv:
        out["table2"]["direct_voting"] = {
            name: _stats(np.array([[j[name] for j in d["joints"]] for d in dv]).reshape(-1, K))
            for name in ("axis_deg", "line_dist")
        }
        out["timing"]["direct_voting_network_ms"] = float(np.mean([d["network_ms"] for d in dv]))
    for name in ("network_ms", "generate_ms"):
        vals = [r[name] for r in recs]
        out["timing"][name] = {"mean": float(np.mean(vals)), "median": float(np.median(vals))} if vals else None
    out["timing"]["wall_s"] = evaluation["timing"]["wall_s"]
    out["occlusion"] = occlusion_bins(evaluation)
    return out


OCCLUSION_EDGES = tuple(np.round(np.arange(0.0, 1.0001, 0.05), 2))


def occlusion_bins(evaluation: dict, edges=OCCLUSION_EDGES) -> dict:
    """Mean rotation / translation error per part and method in bins of the part's visible-area ratio.

    Returns ``{"edges": [...], "parts": [{"name", "counts", <method>: {"rot_deg": [...], "trans": [...]}}]}``
    (``None`` for empty bins; failed fits left out).
    """
    recs = evaluation["records"]
    s = evaluation["settings"]
    edges = np.asarray(edges, dtype=float)
    out = {"edges": edges.tolist(), "parts": []}
    for j, name in enumerate(s["part_names"]):
        vis = np.array([r["visibility"][j] for r in recs])
        idx = np.clip(np.digitize(vis, edges) - 1, 0, len(edges) - 2)
        part = {"name": name, "counts": np.bincount(idx, minlength=len(edges) - 1).tolist()}
        for key in s["methods"]:
            m = {}
            for metric in ("rot_deg", "trans"):
                vals = np.array([r["methods"][key]["parts"][j][metric] if r["methods"][key]["ok"] else np.nan for r in recs])
                m[metric] = []
                for b in range(len(edges) - 1):
                    v = vals[(idx == b) & np.isfinite(vals)]
                    m[metric].append(float(np.mean(v)) if v.size else None)
            part[key] = m
        out["parts"].append(part)
    return out


# --------------------------------------------------------------------------------------------
# report
# --------------------------------------------------------------------------------------------
def _fmt(values, spec: str) -> str:
    if values is None:
        return "-"
    parts = ["-" if v is None or (isinstance(v, float) and not np.isfinite(v)) else format(v, spec) for v in values]
    return "-" if all(p == "-" for p in parts) else ", ".join(parts)


def _state_spec(joint_types) -> str:
    return ".1f" if all(t == "revolute" for t in joint_types) else ".3f"


def _table1(summary: dict, settings: dict, stat: str, paper: dict | None) -> list[str]:
    st = _state_spec(settings["joint_types"])
    lines = [
        "| Method | Rotation error (°) | Translation error | 3D IoU (%) | Joint-state error | Joint-axis angle (°) "
        "| Line–line distance | Failed fits |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for key, row in summary["methods"].items():
        lines.append(
            f"| {METHODS[key].label} | {_fmt(row['rot_deg'][stat], '.2f')} | {_fmt(row['trans'][stat], '.3f')} "
            f"| {_fmt(row['iou'][stat], '.1f')} | {_fmt(row['state_err'][stat], st)} | {_fmt(row['axis_deg'][stat], '.2f')} "
            f"| {_fmt(row['line_dist'][stat], '.3f')} | {row['failures']}/{row['frames']} |"
        )
    for name, row in (paper or {}).items():
        lines.append(
            f"| *paper: {name}* | {_fmt(row.get('rot_deg'), '.1f')} | {_fmt(row.get('trans'), '.3f')} "
            f"| {_fmt(row.get('iou'), '.1f')} | {_fmt(row.get('state_err'), st)} | {_fmt(row.get('axis_deg'), '.1f')} "
            f"| {_fmt(row.get('line_dist'), '.3f')} | |"
        )
    return lines


def _occlusion_table(occ: dict, methods) -> list[str]:
    edges = occ["edges"]
    lines = []
    for part in occ["parts"]:
        used = [b for b, c in enumerate(part["counts"]) if c > 0]
        if not used:
            continue
        lines.append(f"Part **{part['name']}** — mean rotation error (°) per visible-area-ratio bin:\n")
        lines.append("| Method | " + " | ".join(f"{edges[b]:.2f}–{edges[b + 1]:.2f}" for b in used) + " |")
        lines.append("|---|" + "---|" * len(used))
        lines.append("| frames | " + " | ".join(str(part["counts"][b]) for b in used) + " |")
        for key in methods:
            vals = part[key]["rot_deg"]
            lines.append(f"| {METHODS[key].label} | " + " | ".join(_fmt([vals[b]], ".2f") for b in used) + " |")
        lines.append("")
    return lines


def plot_occlusion(summary: dict, settings: dict, path) -> Path:
    """Error vs visible-area ratio (binned means), one column per part, rows: rotation, translation."""
    from matplotlib.figure import Figure

    from ..data.show import save_figure

    occ = summary["occlusion"]
    edges = np.asarray(occ["edges"])
    centres = 0.5 * (edges[:-1] + edges[1:])
    M = len(occ["parts"])
    fig = Figure(figsize=(4.5 * M, 7), dpi=100)
    for j, part in enumerate(occ["parts"]):
        counts = np.array(part["counts"])
        for row, (metric, unit) in enumerate((("rot_deg", "rotation error (°)"), ("trans", "translation error (object units)"))):
            ax = fig.add_subplot(2, M, row * M + j + 1)
            for key in settings["methods"]:
                y = np.array([np.nan if v is None else v for v in part[key][metric]])
                keep = (counts >= 5) & np.isfinite(y)
                ax.plot(centres[keep], y[keep], marker="o", ms=3, label=METHODS[key].label)
            used = np.flatnonzero(counts > 0)
            if used.size:
                ax.set_xlim(edges[used[0]], edges[used[-1] + 1])
            ax.set_xlabel("visible-area ratio of the part")
            ax.set_ylabel(unit)
            ax.grid(alpha=0.3)
            if row == 0:
                ax.set_title(f"part {part['name']} (bins with >= 5 frames)", fontsize=10)
                ax.legend(fontsize=7)
    fig.suptitle(f"{settings.get('category', '')}: mean error vs occlusion on held-out instances", fontsize=11)
    fig.tight_layout()
    return save_figure(fig, path)


def _budget_section(summary: dict, settings: dict) -> list[str]:
    """The error-budget table (:func:`npcs_error_budget`): network NPCS orientation vs fitted rotation."""
    if "budget" not in summary:
        return []
    b = summary["budget"]
    fitted = [key for key in ("per_part", "exact_reduced", "template") if key in summary["methods"]]
    head = "| Part | NPCS head: raw error | NPCS head: orientation error (°) | residual after the similarity |"
    head += "".join(f" {METHODS[k].label}: rotation error (°) |" for k in fitted)
    lines = [
        "",
        "## Where the rotation error comes from (means)",
        "",
        "The network's NPCS for each part, on the points that truly belong to it, against the true NPCS "
        "(`ancsh.studies.table1.npcs_error_budget`). A similarity fitted from the predicted onto the true "
        "NPCS splits their difference into an orientation error (its rotation) and a non-rigid residual. The "
        "orientation error equals the rotation error of a plain Umeyama fit of that part's predicted NPCS "
        "(true labels, no RANSAC): it is carried by the network output, and a fit of one part cannot remove it. "
        "Combining parts under the joints removes only what differs between parts. NPCS distances in NPCS units "
        f"(unit box diagonal). Segmentation accuracy: {b['seg_acc']['mean'][0]:.1%} of points.",
        "",
        head,
        "|---|---|---|---|" + "---|" * len(fitted),
    ]
    for j, name in enumerate(settings["part_names"]):
        row = f"| {name} | {_fmt([b['npcs_err']['mean'][j]], '.3f')} | {_fmt([b['npcs_rot_deg']['mean'][j]], '.2f')} "
        row += f"| {_fmt([b['npcs_resid']['mean'][j]], '.3f')} |"
        row += "".join(f" {_fmt([summary['methods'][k]['rot_deg']['mean'][j]], '.2f')} |" for k in fitted)
        lines.append(row)
    return lines


def refine_summary_line(row: dict) -> str:
    """One sentence on a ``template`` row's refinements: how many were kept, which kind, their cost."""
    r = row["refine"]
    scales = ", ".join(f"{k}: {v}" for k, v in r["scales"].items()) or "none"
    return (f"kept on {r['accepted']}/{r['frames']} frames (articulated {r['choices']['articulated']}, base-only "
            f"{r['choices']['base']}; scales of the kept ones {scales}); the refinement alone costs mean "
            f"{r['refine_ms']['mean']:.0f} ms, median {r['refine_ms']['median']:.0f} ms per frame")


def _refine_lines(summary: dict) -> list[str]:
    row = summary["methods"].get("template")
    if row is None or "refine" not in row:
        return []
    return [f"- category-template refinement: {refine_summary_line(row)} (included in its fit time above)"]


def _per_frame(evaluation: dict) -> dict:
    """Compact per-frame arrays for re-analysis (rounded)."""
    recs = evaluation["records"]
    out = {"instance": [r["instance"] for r in recs], "visibility": [np.round(r["visibility"], 4).tolist() for r in recs]}
    for key in evaluation["settings"]["methods"]:
        m = {}
        for name in ("rot_deg", "trans"):
            m[name] = [[round(p[name], 4) for p in r["methods"][key]["parts"]] or None for r in recs]
        m["state_err"] = [[round(j["state_err"], 4) for j in r["methods"][key]["joints"]] or None for r in recs]
        out[key] = m
    return out


def _json_text(value, pad: str, one_line_entries: bool) -> str:
    """JSON of ``value`` at indentation ``pad``: containers one item a line (``indent=1``), or, where
    ``one_line_entries``, a mapping whose entries each fit on one line."""
    if not isinstance(value, (dict, list)) or not value:
        return json.dumps(value, allow_nan=False)
    inner = pad + " "
    if isinstance(value, list):
        items = [inner + _json_text(v, inner, False) for v in value]
        return "[\n" + ",\n".join(items) + "\n" + pad + "]"
    key = lambda k: json.dumps(k if isinstance(k, str) else json.dumps(k))  # noqa: E731  (JSON's key rule)
    if one_line_entries:
        items = [f"{inner}{key(k)}: {json.dumps(v, allow_nan=False)}" for k, v in value.items()]
    else:
        items = [f"{inner}{key(k)}: {_json_text(v, inner, False)}" for k, v in value.items()]
    return "{\n" + ",\n".join(items) + "\n" + pad + "}"


def write_json(path, data: dict, *, one_line: tuple = ()) -> Path:
    """Write ``data`` (made :func:`json_safe`) as JSON indented by one space a level, except the mappings
    under the top-level keys ``one_line``: each of their entries on one line (per-frame arrays, so
    the file stays small). ``json.loads`` of the file equals ``json_safe(data)``."""
    data = json_safe(data)
    unknown = [k for k in one_line if not isinstance(data.get(k), dict)]
    if unknown:
        raise ValueError(f"one_line: {unknown} are not mapping entries of data")
    inner = " "
    items = [f"{inner}{json.dumps(k)}: {_json_text(v, inner, k in one_line)}" for k, v in data.items()]
    path = Path(path)
    path.write_text("{\n" + ",\n".join(items) + "\n}\n")
    return path


def split_comparison(procedural: dict, sp: dict, real: dict, sr: dict) -> list[str]:
    """Markdown: the real test split's Table 1 means beside the procedural split's, per part and
    method, with their ratio (the real-CAD issue's goal: real <= 1.25x procedural, per part).
    ``sp`` and ``sr`` are the two evaluations' :func:`summarize` results."""
    parts = procedural["settings"]["part_names"]
    joints = procedural["settings"]["joint_names"]
    lines = [
        f"Real test objects ({len(real['settings']['real_instances'])}): "
        f"{', '.join(real['settings']['real_instances'])}; {real['settings']['frames']} real frames, "
        f"{procedural['settings']['frames']} procedural frames (same seeds, noise, points and viewpoints).",
        "",
        "| Method | Part | Rotation (°) procedural | real | ratio | Translation procedural | real | ratio | 3D IoU (%) procedural | real |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]

    def val(row, metric, i):
        v = row[metric]["mean"]
        return None if v is None or v[i] is None else float(v[i])

    def cell(v, spec):
        return "-" if v is None else format(v, spec)

    for key in procedural["settings"]["methods"]:
        rp, rr = sp["methods"][key], sr["methods"][key]
        for i, part in enumerate(parts):
            rot_p, rot_r = val(rp, "rot_deg", i), val(rr, "rot_deg", i)
            tr_p, tr_r = val(rp, "trans", i), val(rr, "trans", i)
            ratio_rot = rot_r / rot_p if rot_p and rot_r is not None else None
            ratio_tr = tr_r / tr_p if tr_p and tr_r is not None else None
            lines.append(
                f"| {METHODS[key].label} | {part} | {cell(rot_p, '.2f')} | {cell(rot_r, '.2f')} | {cell(ratio_rot, '.2f')}x "
                f"| {cell(tr_p, '.3f')} | {cell(tr_r, '.3f')} | {cell(ratio_tr, '.2f')}x "
                f"| {cell(val(rp, 'iou', i), '.1f')} | {cell(val(rr, 'iou', i), '.1f')} |"
            )
    lines += ["", "| Method | Joint | Axis angle (°) procedural | real | State error procedural | real |", "|---|---|---|---|---|---|"]
    for key in procedural["settings"]["methods"]:
        rp, rr = sp["methods"][key], sr["methods"][key]
        for k, joint in enumerate(joints):
            lines.append(f"| {METHODS[key].label} | {joint} | {cell(val(rp, 'axis_deg', k), '.2f')} | "
                         f"{cell(val(rr, 'axis_deg', k), '.2f')} | {cell(val(rp, 'state_err', k), '.3f')} | "
                         f"{cell(val(rr, 'state_err', k), '.3f')} |")
    failures = ", ".join(f"{METHODS[k].label} {sr['methods'][k]['failures']}/{sr['methods'][k]['frames']}"
                         for k in real["settings"]["methods"])
    lines += ["", f"Failed fits on the real split: {failures}."]
    return lines


def write_real_report(procedural: dict, procedural_summary: dict, real: dict, real_summary: dict, out_dir, *,
                      command: str) -> Path:
    """Write ``<category>_real.md``: the real test split beside the procedural one (Table 1, ratios).

    The summaries are the evaluations' :func:`summarize` results (measured by the caller)."""
    category = procedural["category"]
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    date = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    s = real["settings"]
    md = [
        f"# {category}: real test objects beside procedural test instances",
        "",
        f"Command: `{command}`  ",
        f"Date: {date}  ",
        f"Weights: `{Path(s['weights']).name}` (step {s['weights_step']}, sha256 {s['weights_sha256'][:12]})  ",
        f"Real objects: the test split of the catalog `{s['real_catalog']}` (imported PartNet-Mobility objects in the "
        "category's convention, `ancsh data import`), rendered with the same renderer, noise, viewpoints and points "
        "as the procedural test instances. Means over frames; translation in object units; failed fits left out.",
        "",
        *split_comparison(procedural, procedural_summary, real, real_summary),
        "",
        "## Table 1 on the real split (means)",
        "",
        *_table1(real_summary, dict(s), "mean", None),
        "",
    ]
    path = out / f"{category}_real.md"
    path.write_text("\n".join(md))
    return path


def write_report(evaluation: dict, summary: dict, out_dir, *, command: str, real: tuple | None = None) -> dict:
    """Write ``<category>.md``, ``<category>.json`` and ``<category>_occlusion.png`` to ``out_dir``.

    Parameters
    ----------
    evaluation : dict
        :func:`evaluate_category` output (settings and the per-frame records, for ``per_frame``).
    summary : dict
        ``summarize(evaluation)``: the report writes it and computes no statistic itself.
    out_dir : path
    command : str
        The command line that produced ``evaluation`` (quoted in the report).
    real : (dict, dict), optional
        ``(real_evaluation, summarize(real_evaluation))`` of the real test split from the same run:
        the report then shows it beside the procedural split (:func:`split_comparison`) and points to
        ``<category>_real.md`` (:func:`write_real_report`) for its full tables.

    Returns ``{"md", "json", "png"}`` paths. The JSON schema is in ``docs/REPORT_SCHEMAS.md``.
    """
    category = evaluation["category"]
    s = dict(evaluation["settings"], category=category)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = {"md": out / f"{category}.md", "json": out / f"{category}.json", "png": out / f"{category}_occlusion.png"}
    date = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    plot_occlusion(summary, s, paths["png"])
    paper1, paper2 = PAPER_TABLE1.get(category), PAPER_TABLE2.get(category)
    t = summary["timing"]
    parts = ", ".join(s["part_names"])
    joints = ", ".join(f"{n} ({ty})" for n, ty in zip(s["joint_names"], s["joint_types"]))
    state_unit = "degrees" if all(ty == "revolute" for ty in s["joint_types"]) else "object units (prismatic)"
    md = [
        f"# {category}: learned ANCSH on held-out instances",
        "",
        f"Command: `{command}`  ",
        f"Date: {date}  ",
        f"Frames: {s['frames']} (requested {s['frames_requested']}) rendered frames `0..{s['frames'] - 1}` of the test "
        f"stream (seed {s['seed']}) over the {s['test_instances']} held-out {category} instances, "
        f"{s['num_points']} points each, Kinect-like depth noise  ",
        f"Weights: `{Path(s['weights']).name}` (step {s['weights_step']}, sha256 {s['weights_sha256'][:12]})"
        + (f"; direct voting: `{Path(s['direct_weights']).name}`" if s["direct_weights"] else "") + "  ",
        f"Parts (in the order of every list below): {parts}; joints: {joints}",
        "",
        "Statistics: **means** over frames (the paper's official evaluation script averages per part; the paper "
        "does not say), medians in the second table. Failed fits are left out of the statistics and counted. "
        "Rotation in degrees; translation and line–line distance divided by the object scale (object units) as "
        f"in the paper; 3D IoU of the amodal part boxes in %; joint-state error in {state_unit}. "
        "Metrics: `ancsh.evaluation.evaluate_fit`.",
        "",
        "Methods (all fit the output of the one ANCSH network, so they differ only in how they use it): "
        "**NPCS** = per-part Umeyama + RANSAC on the predicted NPCS; **NAOCS** = per-part poses fitted from the "
        "predicted NAOCS `G_s·NPCS + G_t` with the network's per-point `G_s, G_t` (reported as NPCS poses through "
        "the per-part median `G_s, G_t`; with per-part `G` it would equal NPCS exactly; no boxes, as in the paper); **ANCSH-soft** = the paper's combined optimisation with soft joint energies (`soft`, "
        "`FitConfig.paper()`, also used for NPCS and NAOCS); **ANCSH-exact** = joints as exact constraints, reduced "
        "(object pose + joint states) and maximal (all part poses + equality constraints) coordinates, IPOPT, "
        "default `FitConfig()`. The NPCS and NAOCS baselines use the ANCSH network's own heads, not separately "
        "trained networks. " + ("The paper's rows are its Table 1 (its CAD datasets, not our procedural instances)."
                                if paper1 else f"The paper has no {category} category, so no paper rows."),
        "",
        "## Table 1 (means)",
        "",
        *_table1(summary, s, "mean", paper1),
        "",
        "## Table 1 (medians)",
        "",
        *_table1(summary, s, "median", None),
        "",
        "## 3D IoU: estimated box vs a true-size box at the fitted pose (means, %)",
        "",
        "The second column places a box of the part's true size at the fitted pose: when it is low too, the "
        "pose (not the size estimate from the NPCS extents) limits the IoU. Thin parts are the typical case: a "
        "few degrees of rotation move the box faces by more than the part's thickness.",
        "",
        "| Method | 3D IoU, estimated box | 3D IoU, true size at the fitted pose |",
        "|---|---|---|",
        *[f"| {METHODS[key].label} | {_fmt(row['iou']['mean'], '.1f')} | {_fmt(row['iou_pose']['mean'], '.1f')} |"
          for key, row in summary["methods"].items() if key != "naocs"],
        "",
        "## Table 2: joint parameters, direct voting vs ANCSH (means, camera frame)",
        "",
        "| Method | Joint-axis angle (°) | Line–line distance |",
        "|---|---|---|",
    ]
    if "direct_voting" in summary["table2"]:
        dv = summary["table2"]["direct_voting"]
        md.append(f"| Direct voting (PointNet++) | {_fmt(dv['axis_deg']['mean'], '.2f')} | {_fmt(dv['line_dist']['mean'], '.3f')} |")
    else:
        md.append("| Direct voting (PointNet++) | not shipped | not shipped |")
    if "naocs_vote" in summary["table2"]:
        nv = summary["table2"]["naocs_vote"]
        md.append(f"| ANCSH network: voted joints in NAOCS, before fitting | {_fmt(nv['axis_deg']['mean'], '.2f')} "
                  f"| {_fmt(nv['line_dist']['mean'], '.3f')} |")
    for key, row in summary["methods"].items():
        if key in ("soft", "exact_reduced", "exact_maximal", "template"):
            md.append(f"| {METHODS[key].label} | {_fmt(row['axis_deg']['mean'], '.2f')} | {_fmt(row['line_dist']['mean'], '.3f')} |")
    for name, row in (paper2 or {}).items():
        label = "PointNet++ (direct voting)" if name == "direct_voting" else name
        md.append(f"| *paper: {label}* | {_fmt(row.get('axis_deg'), '.1f')} | {_fmt(row.get('line_dist'), '.3f')} |")
    md += ["", "Camera-frame joint errors after fitting include the error of the fitted part poses (the axis is "
           "carried into the camera by the base pose); the NAOCS row measures the network's joint vote alone."]
    if "direct_voting" not in summary["table2"]:
        md += ["", f"No direct-voting network is shipped for {category} (shipped weights: "
               f"{', '.join(s['available_weights']) or 'none'}), so our direct-voting row is missing."]
    md += _budget_section(summary, s)
    md += [
        "",
        "## Occlusion: error vs visible-area ratio",
        "",
        "Visible-area ratio = visible surface area / total surface area of the part (ray-cast surface samples, "
        "as in the paper's supplementary occlusion study). Frames are binned per part by that ratio.",
        "",
        f"![error vs visible-area ratio]({paths['png'].name})",
        "",
        *_occlusion_table(summary["occlusion"], s["methods"]),
        f"## Timings ({describe_machine(s.get('machine'))})",
        "",
        f"- network forward (all points, {s['num_threads']} torch thread(s)), per frame: "
        f"mean {t['network_ms']['mean']:.1f} ms, median {t['network_ms']['median']:.1f} ms",
    ]
    for key, row in summary["methods"].items():
        md.append(f"- fit {METHODS[key].label}: mean {row['fit_ms']['mean']:.1f} ms, median {row['fit_ms']['median']:.1f} ms")
    if "direct_voting_network_ms" in t:
        md.append(f"- direct-voting network + voting: mean {t['direct_voting_network_ms']:.1f} ms")
    md += _refine_lines(summary)
    md += [
        f"- frame rendering (not part of the pipeline): mean {t['generate_ms']['mean']:.1f} ms",
        f"- whole evaluation: {t['wall_s']:.0f} s wall",
        "",
    ]
    if real is not None:
        md += ["## The real test split beside the procedural one (means)", "",
               "The same network and fits on imported real objects of the category's test split, rendered with the "
               "same renderer, noise, viewpoints and points; ratio = real / procedural (the goal: at most 1.25x per "
               f"part). Full tables of the real split: `{category}_real.md`.", "",
               *split_comparison(evaluation, summary, real[0], real[1]), ""]
    paths["md"].write_text("\n".join(md))
    from .._version import __version__

    data = {
        "category": category, "command": command, "date": date, "ancsh_version": __version__, "settings": s, "summary": summary,
        "paper": {"table1": paper1, "table2": paper2}, "per_frame": _per_frame(evaluation),
    }
    if real is not None:  # the real split's summary, so that its figures can be read back (ancsh weights --reports)
        rs = real[0]["settings"]
        data["real"] = {"settings": {k: rs[k] for k in ("frames", "real_catalog", "real_instances", "weights_sha256")},
                        "summary": {k: real[1][k] for k in ("methods", "table2", "budget") if k in real[1]}}
    write_json(paths["json"], data, one_line=("per_frame",))
    return paths
