"""The learned correspondence provider: ANCSH network output -> :class:`~ancsh.solvers.types.Correspondences`.

:class:`LearnedProvider` implements the ``CorrespondenceProvider`` protocol, so every solver
formulation runs on network predictions unchanged. Per observation it

1. runs the network on the whole cloud in chunks of ``num_points`` (each chunk a random,
   seeded subset, padded by repetition), so every observed point gets a prediction;
2. labels each point with its most likely part and takes that part's NPCS;
3. sets each part's NPCS -> NAOCS scale and translation ``G_s, G_t`` to the median of the
   per-point predictions over the points labelled with that part (over all points when a
   part received no point);
4. votes every joint's axis and pivot in NAOCS (:mod:`.voting`) from the points associated
   with it (the most likely ``min_votes`` points by association probability when too few
   points were labelled).

Per-point weights are the segmentation confidences (softmax probability of the chosen part).
:class:`DirectVotingPredictor` gives the camera-space joints of the direct-voting baseline.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...geometry._checks import check_generator
from ...model.articulated import JointType
from ...solvers.types import Correspondences, Observation
from .refine_network import DEFAULT_PASSES
from .voting import JointVote, vote_joints

__all__ = ["REFINE_OPTIONS", "Inference", "LearnedProvider", "Prediction", "DirectVotingPredictor", "RefinedFit",
           "apply_refinement", "predict_points"]

REFINE_OPTIONS = (None, "none", "template", "network", "auto")
"""Values of ``LearnedProvider(refine=...)``."""


@dataclass(frozen=True)
class Prediction:
    """Raw per-point network output for ``N`` observed points (numpy, float64).

    Attributes
    ----------
    seg_prob : (N, M)
        Part probabilities.
    npcs : (N, M, 3) or None
        NPCS for every part hypothesis (ANCSH network only).
    scale : (N, M) or None
        NPCS -> NAOCS scale per hypothesis.
    translation : (N, M, 3) or None
    assoc_prob : (N, K + 1)
        Joint-association probabilities (column 0 = none).
    joint : (N, 7)
        Joint votes (NAOCS for ANCSH; camera frame with the distance in metres for direct voting).
    """

    seg_prob: np.ndarray
    npcs: np.ndarray | None
    scale: np.ndarray | None
    translation: np.ndarray | None
    assoc_prob: np.ndarray
    joint: np.ndarray


def predict_points(model, points_cam: np.ndarray, num_points: int, rng) -> Prediction:
    """Run ``model`` over all ``(N, 3)`` camera-frame points in seeded chunks of ``num_points``.

    Points are shuffled and split into ``ceil(N / num_points)`` equal-size chunks, each padded
    to ``num_points`` with random repeats of its cloud, and evaluated as one batch on the device
    of the model's parameters.
    """
    import torch

    rng = check_generator(rng)
    N = points_cam.shape[0]
    if N == 0:
        raise ValueError("points_cam: no points")
    chunks = int(np.ceil(N / num_points))
    order = rng.permutation(N)
    parts = np.array_split(order, chunks)
    batch = np.empty((chunks, num_points), dtype=np.int64)
    for c, idx in enumerate(parts):
        pad = rng.choice(N, size=num_points - idx.size, replace=N < num_points - idx.size) if idx.size < num_points else []
        batch[c] = np.concatenate([idx, np.asarray(pad, dtype=np.int64)])
    from ..devices import model_device

    x = torch.from_numpy(points_cam[batch].astype(np.float32)).to(model_device(model))
    model.eval()
    with torch.no_grad():
        out = {k: v.double().cpu().numpy() for k, v in model(x).items()}

    def scatter(key, fn=None):
        if key not in out:
            return None
        v = out[key]
        if fn is not None:
            v = fn(v)
        res = np.empty((N, *v.shape[2:]))
        for c, idx in enumerate(parts):
            res[idx] = v[c, : idx.size]
        return res

    return Prediction(
        seg_prob=scatter("seg_logits", _softmax),
        npcs=scatter("npcs"),
        scale=scatter("scale"),
        translation=scatter("translation"),
        assoc_prob=scatter("assoc_logits", _softmax),
        joint=scatter("joint"),
    )


def _softmax(x: np.ndarray) -> np.ndarray:
    e = np.exp(x - x.max(-1, keepdims=True))
    return e / e.sum(-1, keepdims=True)


def _joint_sets(assoc_prob: np.ndarray, K: int, min_votes: int) -> np.ndarray:
    """Association labels where every joint has at least ``min_votes`` voters (most likely points)."""
    assoc = assoc_prob.argmax(1)
    counts = np.bincount(assoc, minlength=K + 1)
    for k in range(K):
        if counts[k + 1] < min_votes:
            # the most likely points of joint k, never taken from a joint they would leave short of voters
            free = np.flatnonzero((assoc == k + 1) | (assoc == 0) | (counts[assoc] > min_votes))
            top = free[np.argsort(-assoc_prob[free, k + 1], kind="stable")]
            for i in top:
                if assoc[i] == 0 or (assoc[i] != k + 1 and counts[assoc[i]] > min_votes):
                    counts[assoc[i]] -= 1
                    assoc[i] = k + 1
                    counts[k + 1] += 1
                if counts[k + 1] >= min_votes:
                    break
    return assoc


@dataclass(frozen=True)
class Inference:
    """One pass of :class:`LearnedProvider` over an observation.

    Attributes
    ----------
    correspondences : Correspondences
        What the solvers use.
    prediction : Prediction
        The network's raw per-point output behind them.
    votes : tuple of JointVote
        The NAOCS joint votes (one per joint).
    """

    correspondences: Correspondences
    prediction: Prediction
    votes: tuple


def _place(network, device) -> None:
    """Move a loaded network's model to ``device`` (``None``: leave it where it is)."""
    if device is not None:
        from ..devices import resolve_device

        network.model.to(resolve_device(device))


class LearnedProvider:
    """Correspondences from the ANCSH network.

    Parameters
    ----------
    source : str, Path or LoadedNetwork
        Category name (shipped weights), a weights/checkpoint file, or a loaded network.
    seed : int
        Seeds the chunking of large clouds (results are deterministic per observation).
    num_threads : int, optional
        torch intra-op threads (default: leave torch's setting).
    min_votes : int
        Least voters per joint.
    refine : str or None
        What :meth:`refine` does with a fit of these correspondences: ``"template"`` refines it against
        the category template (:func:`ancsh.solvers.icp.category.refine_fit`, the nearest training
        instance of the network's category; kept only where its score on the observed points beats the
        fit's), ``"network"`` runs the refinement network ``refiner`` on the points in the fit's NAOCS
        orientation and fits again (:func:`~ancsh.learned.inference.refine_network.refine_with_network`),
        ``None`` / ``"none"`` leaves it, ``"auto"`` does what was measured to help the category most
        (:func:`ancsh.data.templates.refine_default`: the template, the refinement network or neither).
    refiner : str, Path or LoadedNetwork, optional
        With ``refine="network"``: the refinement network (default: the category's shipped
        ``<category>_refine.pt``, also what ``"auto"`` uses), loaded when first needed.
    refine_passes : int
        Passes of the refinement network.
    device : str or torch.device, optional
        Where the network runs: ``"cpu"``, ``"cuda"``, ``"auto"`` (:func:`~ancsh.learned.devices.resolve_device`);
        the network is moved there. Default: where it is (the CPU for a loaded file).
    joint_limits : "category", None or (K, 2) array
        The joint ranges (relative to rest) the fits of these correspondences are bounded by: ``"category"`` (default)
        the network category's :attr:`~ancsh.data.conventions.CategoryConvention.joint_limits` where it has a
        convention of the network's structure (none otherwise), ``None`` none, or the array itself.
    category : Category, optional
        The network's category as loaded by the caller (:func:`~ancsh.learned.inference.category.load_category`): its
        convention (joint limits), refinement network, ``"auto"`` choice and template come from it. Default: the
        category the network's training config names, loaded here once.
    """

    def __init__(self, source, *, seed: int = 0, num_threads: int | None = None, min_votes: int = 5,
                 refine: str | None = None, refiner=None, refine_passes: int = DEFAULT_PASSES, device=None,
                 joint_limits="category", category=None):
        from ..network.weights import LoadedNetwork, load_network
        from .category import Category, load_category

        self.network = source if isinstance(source, LoadedNetwork) else load_network(source)
        if self.network.kind != "ancsh":
            raise ValueError(f"source: expected an ANCSH network, got a {self.network.kind!r} network")
        if category is not None and not isinstance(category, Category):
            raise ValueError(f"category: expected a Category (load_category) or None, got {category!r}")
        own = getattr(self.network.config, "category", None)
        if category is not None and own is not None and own != category.name:
            raise ValueError(f"category: the network is a {own} network, not a {category.name} one")
        #: The network's :class:`~ancsh.learned.inference.category.Category` (``None`` for a network naming none).
        self.category_info = category if category is not None else (
            None if own is None else load_category(own, network_category=own))
        _place(self.network, device)
        if num_threads is not None:
            import torch

            torch.set_num_threads(int(num_threads))
        self.seed = int(seed)
        self.min_votes = int(min_votes)
        self.joint_types = tuple(JointType.REVOLUTE if r else JointType.PRISMATIC for r in self.network.revolute)
        self.joint_limits = self._joint_limits(joint_limits)
        if refine not in REFINE_OPTIONS:
            raise ValueError(f"refine: expected one of {REFINE_OPTIONS}, got {refine!r}")
        self.refine_option = None if refine == "none" else refine
        if isinstance(refine_passes, bool) or int(refine_passes) != refine_passes or refine_passes < 1:
            raise ValueError(f"refine_passes: expected a positive integer, got {refine_passes!r}")
        self.refine_passes = int(refine_passes)
        self._refiner_source = refiner
        self._refiner: LearnedProvider | None = None
        self._device = device
        if self.refine_option == "network":
            self.refiner  # load it now: a missing or wrong refinement network is the first thing to hear about
        elif refiner is not None:
            raise ValueError(f"refiner: a refinement network is used with refine='network' only, not refine={refine!r}")

    def _joint_limits(self, joint_limits):
        """The ``(K, 2)`` limits of the ``joint_limits`` option (``None`` for none)."""
        K = len(self.joint_types)
        if joint_limits is None:
            return None
        if isinstance(joint_limits, str):
            if joint_limits != "category":
                raise ValueError(f"joint_limits: expected 'category', None or a (K, 2) array, got {joint_limits!r}")
            conv = None if self.category_info is None else self.category_info.convention
            if conv is None or conv.joint_types != self.joint_types:
                return None
            return conv.joint_limits
        limits = np.asarray(joint_limits, dtype=np.float64)
        if limits.shape != (K, 2):
            raise ValueError(f"joint_limits: expected a ({K}, 2) array of (lower, upper), got shape {limits.shape}")
        return limits

    @property
    def refiner(self) -> "LearnedProvider":
        """A provider of the refinement network (``refine="network"``), loaded on first use."""
        if self._refiner is None:
            from ..network.weights import LoadedNetwork, load_network

            source = self._refiner_source
            if source is None:
                expected = None if self.category_info is None else self.category_info.weights_path("refine")
                if expected is None or not expected.is_file():
                    raise FileNotFoundError(f"refiner: no refinement network is shipped for {self.category!r} "
                                            f"(expected {expected or '<category>_refine.pt'}); give one")
                source = expected
            net = source if isinstance(source, LoadedNetwork) else load_network(source)
            if not net.config.is_refiner:
                raise ValueError(f"refiner: {net.source} is a first-stage network, not a refinement network")
            if net.num_parts != self.num_parts or not np.array_equal(net.revolute, self.network.revolute):
                raise ValueError(f"refiner: {net.source} predicts {net.num_parts} parts and joints "
                                 f"{net.revolute.tolist()}, the first stage {self.num_parts} and {self.network.revolute.tolist()}")
            self._refiner = LearnedProvider(net, seed=self.seed, min_votes=self.min_votes, device=self._device,
                                            category=self.category_info)
        return self._refiner

    @property
    def category(self) -> str | None:
        """The network's category name (the given :class:`Category`'s, else its training config's)."""
        if self.category_info is not None:
            return self.category_info.name
        return getattr(self.network.config, "category", None)

    def fit_config(self, **overrides):
        """The :class:`~ancsh.solvers.fit.FitConfig` of this provider's fits: the defaults with the objective
        :data:`~ancsh.solvers.formulations.DEFAULT_OBJECTIVES` names for the shipped networks of :attr:`category`
        (``FitConfig.default_for("learned", category)``), then ``overrides`` (e.g. ``box_extents``)."""
        from ...solvers.fit import FitConfig

        return FitConfig.default_for("learned", self.category, **overrides)

    def refines(self, refine: str | None = "provider") -> bool:
        """Whether :meth:`refine` refines (``refine``: an override of the provider's option, as there)."""
        return self.refine_choice(refine) is not None

    def refine_choice(self, refine: str | None = "provider") -> str | None:
        """What :meth:`refine` does: ``"template"``, ``"network"`` or ``None`` (``refine``: an override of the
        provider's option, as there; ``"auto"`` resolved by the category's measured choice,
        :func:`ancsh.data.templates.refine_default`)."""
        option = self.refine_option if refine == "provider" else refine
        if option not in REFINE_OPTIONS:
            raise ValueError(f"refine: expected one of {REFINE_OPTIONS}, got {option!r}")
        if option == "auto":
            return None if self.category_info is None else self.category_info.refine_default
        return option if option in ("template", "network") else None

    def refine(self, observation: Observation, corr: Correspondences, fit, *, refine: str | None = "provider", rng=0,
               config=None):
        """A fit of this provider's correspondences, refined against the category template when enabled.

        Parameters
        ----------
        observation : Observation
        corr : Correspondences
            What :meth:`correspond` gave for ``observation``.
        fit : FitResult
            Their fit (an articulated formulation, e.g. ``exact_reduced``).
        refine : str or None
            Overrides the provider's ``refine`` option (default: use it).
        rng : numpy.random.Generator or int
        config : FitConfig, optional
            Of the refinement network's fits (give the first fit's, e.g. its ``box_extents``; default:
            :meth:`fit_config`). The template refinement (articulated ICP) does not use it.

        Returns
        -------
        TemplateRefinement, NetworkRefinement or None
            ``None`` when refinement is off; else its outcome (``.result`` is the fit to use).
        """
        choice = self.refine_choice(refine)
        if choice is None:
            return None
        if choice == "network":
            from .refine_network import refine_with_network

            return refine_with_network(self.refiner, observation, fit, formulation=fit.formulation,
                                       passes=self.refine_passes, rng=rng,
                                       config=self.fit_config() if config is None else config)
        from ...solvers.icp.category import refine_fit

        if self.category_info is None or not self.category_info.has_templates():
            raise ValueError(f"refine: the network's category {self.category!r} has no template library")
        return refine_fit(observation, fit, corr, self.category_info.template_library(), rng=rng)

    @property
    def num_parts(self) -> int:
        return self.network.num_parts

    @property
    def num_joints(self) -> int:
        return len(self.joint_types)

    def check_structure(self, part_names, joint_types, where: str = "object") -> None:
        """Refuse an object whose structure this network does not predict.

        Parameters
        ----------
        part_names : sequence of str
            The object's parts (label order).
        joint_types : sequence of JointType or str
            The object's joint types (joint order).
        where : str
            What the object is, for the message.

        Raises
        ------
        ValueError
            When the part count or the joint types differ (a 2-part cabinet against a 4-part
            drawer network would otherwise be fitted and scored on the wrong parts).
        """
        types = tuple(JointType(t) for t in joint_types)
        category = getattr(self.network.config, "category", "?")
        if len(part_names) != self.num_parts or types != self.joint_types:
            raise ValueError(
                f"{where}: has {len(part_names)} parts and joints {[t.value for t in types]}, but the {category} network "
                f"predicts {self.num_parts} parts and joints {[t.value for t in self.joint_types]}"
            )

    def predict(self, points_cam, *, input_rotation=None) -> Prediction:
        """Raw per-point predictions for ``(N, 3)`` camera-frame points (metres).

        ``input_rotation`` ``(3, 3)``: the network sees the points rotated by it (a refinement network's
        input, :attr:`~ancsh.learned.network.config.TrainConfig.refine_perturb_deg`: the transpose of a
        first fit's ``R_cam_naocs``). Its predictions are canonical (NPCS, NAOCS), so they hold for the
        unrotated points too.
        """
        pts = Observation(points_cam).points_cam
        if input_rotation is None and self.network.config.is_refiner:
            raise ValueError(f"input_rotation: {self.network.source} is a refinement network; it takes the points "
                             "rotated into a first fit's NAOCS orientation (use it as refiner=, refine='network')")
        if input_rotation is not None:
            R = np.asarray(input_rotation, dtype=np.float64)
            if R.shape != (3, 3) or not np.all(np.isfinite(R)) or not np.allclose(R @ R.T, np.eye(3), atol=1e-6) \
                    or np.linalg.det(R) < 0:
                raise ValueError(f"input_rotation: expected a (3, 3) rotation matrix, got {R.tolist()}")
            pts = pts @ R.T
        return predict_points(self.network.model, pts, self.network.config.num_points, self.seed)

    def correspond(self, observation: Observation, *, input_rotation=None) -> Correspondences:
        """Per-point part labels, NPCS, per-part ``G_s, G_t`` and voted NAOCS joints for ``observation``
        (``input_rotation``: as for :meth:`predict`)."""
        return self.infer(observation, input_rotation=input_rotation).correspondences

    def infer(self, observation: Observation, *, input_rotation=None) -> "Inference":
        """:meth:`correspond`'s correspondences with the raw prediction and the joint votes behind them."""
        if not isinstance(observation, Observation):
            raise ValueError(f"observation: expected an Observation, got {type(observation).__name__}")
        if observation.num_points == 0:
            raise ValueError("observation: no points")
        pred = self.predict(observation.points_cam, input_rotation=input_rotation)
        M, K = self.num_parts, self.num_joints
        N = observation.num_points
        labels = pred.seg_prob.argmax(1)
        rows = np.arange(N)
        npcs = pred.npcs[rows, labels]
        scale = np.empty(M)
        trans = np.empty((M, 3))
        for j in range(M):
            sel = labels == j if np.any(labels == j) else np.ones(N, dtype=bool)
            scale[j] = np.median(pred.scale[sel, j])
            trans[j] = np.median(pred.translation[sel, j], axis=0)
        naocs = scale[labels, None] * npcs + trans[labels]
        assoc = _joint_sets(pred.assoc_prob, K, max(1, min(self.min_votes, N // max(K, 1))))
        votes = vote_joints(naocs, assoc, pred.joint, self.network.revolute, min_votes=1)
        corr = Correspondences(
            part_labels=labels,
            npcs=npcs,
            npcs_scale=scale,
            npcs_translation=trans,
            joint_types=self.joint_types,
            joint_parents=self.network.joint_parents,
            joint_children=self.network.joint_children,
            joint_axes_naocs=np.array([v.axis for v in votes]).reshape(K, 3),
            joint_pivots_naocs=np.array([v.pivot for v in votes]).reshape(K, 3),
            weights=pred.seg_prob[rows, labels],
            joint_limits=self.joint_limits,
        )
        return Inference(corr, pred, tuple(votes))


@dataclass(frozen=True)
class RefinedFit:
    """A fit after :func:`apply_refinement`: what to report and judge it by.

    Attributes
    ----------
    result : FitResult
        The refined fit where a refinement was accepted, else the input fit.
    correspondences : Correspondences
        Those the result was fitted to (the refinement network's where its fit is kept).
    prediction : Prediction or None
        The network output behind them.
    kind : str or None
        ``"template"`` or ``"network"``: the accepted refinement that made ``result``; ``None``: none.
    note : str or None
        One line on what the refinement did (``None`` when none ran).
    """

    result: object
    correspondences: Correspondences
    prediction: object
    kind: str | None
    note: str | None


def apply_refinement(provider: LearnedProvider, observation: Observation, corr: Correspondences, prediction, fit, *,
                     refine: str | None = "provider", rng=0) -> RefinedFit:
    """Refine ``fit`` (of ``corr``, the network output ``prediction``) as ``provider`` is set to
    (:meth:`LearnedProvider.refine`; ``refine`` overrides its option) and say what the result rests on -- the
    one rule of ``ancsh predict`` and the calibrations measured for its fits."""
    from .refine_network import NetworkRefinement

    refined = provider.refine(observation, corr, fit, refine=refine, rng=rng) if fit.ok else None
    if refined is None:
        return RefinedFit(fit, corr, prediction, None, None)
    if isinstance(refined, NetworkRefinement):
        note = (f"refinement network: {'kept' if refined.accepted else 'not kept'} ({refined.reason}; rotation moved "
                f"{', '.join(f'{a:.1f}' for a in refined.rotation_change_deg) or '-'} deg per pass, "
                f"{1e3 * refined.time_s:.0f} ms)")
        if refined.accepted:
            return RefinedFit(refined.result, refined.inference.correspondences, refined.inference.prediction, "network",
                              note)
        return RefinedFit(fit, corr, prediction, None, note)
    note = (f"category-template refinement: {'kept' if refined.accepted else 'not kept'} ({refined.reason}; template "
            f"{refined.template or 'none'}, {1e3 * refined.time_s:.0f} ms)")
    return RefinedFit(refined.result, corr, prediction, "template" if refined.accepted else None, note)


class DirectVotingPredictor:
    """Camera-space joint axes and pivots from the direct joint-voting baseline network.

    Parameters
    ----------
    source : str, Path or LoadedNetwork
        Category name (looks up ``<category>_direct_voting.pt``) or a file.
    seed : int
    min_votes : int
    device : str or torch.device, optional
        As for :class:`LearnedProvider`.
    """

    def __init__(self, source, *, seed: int = 0, min_votes: int = 5, device=None):
        from ..network.weights import LoadedNetwork, load_network

        self.network = source if isinstance(source, LoadedNetwork) else load_network(source, kind="direct_voting")
        if self.network.kind != "direct_voting":
            raise ValueError(f"source: expected a direct_voting network, got a {self.network.kind!r} network")
        _place(self.network, device)
        self.seed = int(seed)
        self.min_votes = int(min_votes)

    def joints(self, observation: Observation) -> tuple[np.ndarray, np.ndarray, tuple[JointVote, ...]]:
        """``(axes_cam (K, 3), pivots_cam (K, 3) metres, votes)`` for an observation."""
        if not isinstance(observation, Observation):
            raise ValueError(f"observation: expected an Observation, got {type(observation).__name__}")
        if observation.num_points == 0:
            raise ValueError("observation: no points")
        pts = observation.points_cam
        pred = predict_points(self.network.model, pts, self.network.config.num_points, self.seed)
        K = len(self.network.revolute)
        assoc = _joint_sets(pred.assoc_prob, K, max(1, min(self.min_votes, pts.shape[0] // max(K, 1))))
        votes = vote_joints(pts, assoc, pred.joint, self.network.revolute, min_votes=1)
        return np.array([v.axis for v in votes]).reshape(K, 3), np.array([v.pivot for v in votes]).reshape(K, 3), votes
