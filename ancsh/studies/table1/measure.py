"""Measuring ``ancsh evaluate``'s Table 1 / Table 2: the methods and the per-frame records on held-out instances.

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
    Joints as exact constraints (IPOPT), the provider's ``FitConfig``
    (:meth:`~ancsh.learned.inference.provider.LearnedProvider.fit_config`: the shipped networks' default objective,
    :data:`ancsh.solvers.formulations.DEFAULT_OBJECTIVES`).
``network`` (ANCSH-exact + refinement network, ours; only when asked for, ``refine="network"``)
    The ``exact_reduced`` fit refined by the category's refinement network
    (:func:`ancsh.learned.inference.refine_network.refine_with_network`: the points rotated into the fit's
    NAOCS orientation, the network run again, the exact fit again; ``refine_passes`` passes), the ``exact_reduced``
    fit itself where no pass succeeded.
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

import dataclasses
import time
from dataclasses import dataclass

import numpy as np

from ..._machine import machine_facts
from ...solvers.types import Correspondences, FitResult, Observation
from ...data.procedural import generator_version
from ...learned.inference.refine_network import DEFAULT_PASSES
from ...learned.network.weights import missing_weights_error
from ...learned.network.weights import shipped_categories  # noqa: F401  (re-exported: the evaluation's category list)
from ...outputs import json_safe  # noqa: F401  (re-exported)

__all__ = ["DEFAULT_METHODS", "METHODS", "REFINEMENTS", "PAPER_TABLE1", "PAPER_TABLE2", "Method", "TIMING_KEYS", "evaluate_category",
           "fit_method", "fit_naocs", "naocs_correspondences", "npcs_error_budget", "per_point_naocs"]


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
        Method("network", "ANCSH-exact + refinement network (ours)", "exact_reduced", False),
    )
}
"""Methods of Table 1 by key (``--formulations`` takes these keys)."""

REFINEMENTS = ("template", "network")
"""Methods that refine an ``exact_reduced`` fit (asked for with ``refine``)."""

DEFAULT_METHODS = tuple(k for k in METHODS if k not in REFINEMENTS)
"""The methods evaluated by default (the refinements cost more per frame or need a refinement network: asked for
with ``refine``)."""

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
    from ...geometry._checks import as_array

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
    from ...geometry.transforms import Sim3
    from ...solvers import fit

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


def fit_method(key: str, observation: Observation, corr: Correspondences, *, naocs=None, rng=0,
               config=None) -> FitResult:
    """Fit one :data:`METHODS` entry to the network's correspondences (``naocs``: per-point NAOCS for ``"naocs"``).

    ``config``: the :class:`~ancsh.solvers.fit.FitConfig` of the methods without the paper's config (the
    ``exact_*`` rows; give the provider's, :meth:`~ancsh.learned.inference.provider.LearnedProvider.fit_config`);
    default ``FitConfig()``. The paper's rows use ``FitConfig.paper()``."""
    from ...solvers import FitConfig, fit

    if key not in METHODS:
        raise ValueError(f"key: expected one of {list(METHODS)}, got {key!r}")
    if key in REFINEMENTS:
        raise ValueError(f"key: {key!r} refines an exact_reduced fit (ancsh.solvers.icp.category.refine_fit, "
                         "ancsh.learned.inference.refine_network.refine_with_network)")
    m = METHODS[key]
    config = FitConfig.paper() if m.paper_config else FitConfig() if config is None else config
    if key == "naocs":
        return fit_naocs(observation, corr, naocs=naocs, config=config, rng=rng)
    return fit(observation, corr, m.formulation, config=config, rng=rng)


# --------------------------------------------------------------------------------------------
# the evaluation loop
# --------------------------------------------------------------------------------------------
def _direct_joint_errors(axes, pivots, gt) -> list[dict]:
    from ...geometry.metrics import axis_angle_error_deg, line_distance

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
    from ...geometry.metrics import axis_angle_error_deg, line_distance

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
    from ...geometry import umeyama
    from ...geometry.rotations import rotation_angle

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
                 device="cpu", instances: str = "test", refiner=None, real_split=None, refine_passes: int = DEFAULT_PASSES):
        from ...data.generate import FrameGenerator, GenerationConfig
        from ...learned.inference.provider import DirectVotingPredictor, LearnedProvider

        cfg = dict(category=category, split=instances, seed=int(seed))
        if real is not None:
            cfg.update(real=real, real_fraction=1.0, real_split=real_split)
        self.generator = FrameGenerator(GenerationConfig(**cfg))
        self.provider = LearnedProvider(weights, seed=seed, num_threads=num_threads, device=device,
                                        refine="network" if "network" in methods else None, refiner=refiner,
                                        refine_passes=refine_passes)
        self.voter = None if direct_weights is None else DirectVotingPredictor(direct_weights, seed=seed, device=device)
        self.seed, self.methods = int(seed), tuple(methods)
        self.fit_config = self.provider.fit_config()  # the exact rows: the network's default objective
        self.library = None
        if "template" in self.methods:
            from ...data.templates import load_template_library

            self.library = load_template_library(category)

    def __call__(self, i: int) -> dict:
        from ...evaluation import evaluate_fit

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
            if key in REFINEMENTS:
                continue
            r = fits[key] = fit_method(key, obs, corr, naocs=naocs, rng=self.seed + i, config=self.fit_config)
            ev = evaluate_fit(r, fr.gt, fr.part_names, fr.joint_names).to_dict()
            ev["fit_ms"] = 1e3 * r.time_s
            rec["methods"][key] = ev
        if self.library is not None:
            from ...solvers.icp.category import refine_fit

            base = fits["exact_reduced"] if "exact_reduced" in fits else fit_method("exact_reduced", obs, corr, rng=self.seed + i,
                                                                                          config=self.fit_config)
            ref = refine_fit(obs, base, corr, self.library, rng=self.seed + i)
            ev = evaluate_fit(ref.result, fr.gt, fr.part_names, fr.joint_names).to_dict()
            ev["fit_ms"] = 1e3 * ref.result.time_s if ref.accepted else 1e3 * (base.time_s + ref.time_s)
            ev["refine"] = {"accepted": ref.accepted, "choice": ref.choice, "scale": ref.scale, "template": ref.template,
                            "refine_ms": 1e3 * ref.time_s, "score_input": ref.score_input,
                            "score_refined": ref.score_refined}
            rec["methods"]["template"] = ev
        if "network" in self.methods:
            base = fits["exact_reduced"] if "exact_reduced" in fits else fit_method("exact_reduced", obs, corr, rng=self.seed + i,
                                                                                          config=self.fit_config)
            if base.ok:
                ref = self.provider.refine(obs, corr, base, refine="network", rng=self.seed + i)
                ev = evaluate_fit(ref.result, fr.gt, fr.part_names, fr.joint_names).to_dict()
                ev["fit_ms"] = 1e3 * (base.time_s + ref.time_s)
                ev["network_refine"] = {"accepted": ref.accepted, "passes": ref.passes,
                                        "rotation_change_deg": list(ref.rotation_change_deg), "refine_ms": 1e3 * ref.time_s}
            else:
                ev = evaluate_fit(base, fr.gt, fr.part_names, fr.joint_names).to_dict()
                ev["fit_ms"] = 1e3 * base.time_s
            rec["methods"]["network"] = ev
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
    refine=None,
    refiner=None,
    refine_passes: int | None = None,
    executor=None,
    device="cpu",
    instances: str = "test",
    real_split: str | None = None,
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
    refine : str or sequence of str, optional
        ``"template"``: add the ``template`` method (the ``exact_reduced`` fit refined against the
        category's template library, :func:`ancsh.data.templates.load_template_library`); ``"network"``:
        add the ``network`` method (refined by the refinement network ``refiner``); both (a sequence): both
        rows, on the same network output.
    real_split : str, optional
        With ``real``: ``"all"`` renders every imported object of the category (train and test objects; the
        training objects were seen in training) instead of the ``instances`` split's.
    refiner : str or Path, optional
        The refinement network of the ``network`` method (default: the category's shipped ``<category>_refine.pt``).
    refine_passes : int, optional
        Passes of the refinement network in the ``network`` method (default
        :data:`~ancsh.learned.inference.refine_network.DEFAULT_PASSES`, as ``LearnedProvider``).
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
    from ...data.generate import FrameGenerator, GenerationConfig
    from ...executors import LocalExecutor, RayExecutor
    from ...learned.devices import resolve_device
    from ...learned.network.weights import available_weights, load_network, weights_path

    methods = tuple(methods)
    refinements = () if refine is None else (refine,) if isinstance(refine, str) else tuple(refine)
    if not all(isinstance(r, str) and r in REFINEMENTS for r in refinements):
        raise ValueError(f"refine: expected None, one of {REFINEMENTS} or a sequence of them, got {refine!r}")
    methods = methods + tuple(r for r in dict.fromkeys(refinements) if r not in methods)
    if refiner is not None and "network" not in methods:
        raise ValueError("refiner: a refinement network is evaluated with refine='network' only")
    if refine_passes is not None and (isinstance(refine_passes, bool) or not isinstance(refine_passes, (int, np.integer))
                                      or refine_passes < 1):
        raise ValueError(f"refine_passes: expected a positive integer, got {refine_passes!r}")
    if refine_passes is not None and "network" not in methods:
        raise ValueError("refine_passes: the refinement network's passes are evaluated with refine='network' only")
    passes = DEFAULT_PASSES if refine_passes is None else int(refine_passes)
    bad = [m for m in methods if m not in METHODS]
    if bad or not methods:
        raise ValueError(f"methods: expected keys of {list(METHODS)}, got {list(methods)}")
    if isinstance(frames, bool) or int(frames) != frames or frames < 1:
        raise ValueError(f"frames: expected a positive integer, got {frames!r}")
    if real_split is not None and real is None:
        raise ValueError("real_split: needs a real catalog (real=...)")
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
                                              real_fraction=1.0, real_split=real_split))
        if not gen.real_instances:
            which = "imported" if real_split == "all" else instances
            raise ValueError(f"real: the catalog {real!r} has no real {which} object of {category!r}")
    if weights is None and not weights_path(category).is_file():
        raise missing_weights_error(category)
    network = load_network(category if weights is None else weights)  # its file and SHA-256 at load time
    if network.kind != "ancsh":
        raise ValueError(f"weights: expected an ANCSH network, got a {network.kind!r} network")
    refiner_source = refiner_net = None
    if "network" in methods:  # loaded here: a missing or mismatched refinement network fails before any frame
        from ...learned.inference.provider import LearnedProvider

        refiner_net = LearnedProvider(network, refine="network", refiner=refiner).refiner.network
        refiner_source = refiner_net.source
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
    worker_args = (category, int(seed), real, network.source, direct, int(num_threads), methods, device, instances,
                   refiner_source, real_split, passes)
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
            "real_split": real_split if real is not None else None,
            "num_points": gen.config.num_points, "generator_version": generator_version(category),
            "part_names": list(fr0.part_names), "joint_names": list(fr0.joint_names),
            "joint_types": [t.value for t in fr0.gt.joint_types],
            "time_limit_s": time_limit_s,
            "refine": (refinements[0] if len(refinements) == 1 else list(refinements)) if refinements else None,
            "refiner": refiner_source,
            "refiner_step": None if refiner_net is None else refiner_net.step,
            "refiner_sha256": None if refiner_net is None else refiner_net.sha256,
            "refine_passes": None if refiner_net is None else passes,
            "executor": executor.describe(), "device": device,
        },
        "timing": {"wall_s": time.perf_counter() - start},
    }


