"""Every object of a category through a depth sequence: one track per object, with a stable id.

:class:`MultiObjectTracker` steps on whole depth images. Per frame:

1. **Regions.** Each live track's fitted model is posed where it was last measured (after a frame without a
   measurement: at its state predicted by the :class:`~ancsh.tracking.state_filter.StateFilter`); its pixels are the
   valid pixels whose points lie inside one of its part boxes grown by ``region_margin`` object diagonals, at least
   ``support_clearance`` above the surface it stands on (the lowest well-supported plane of the depth under it,
   :func:`~ancsh.tracking.regions.support_height`: the table or floor is not the object). A pixel in two tracks'
   regions goes to the one it lies deeper inside.
2. **Measurements.** Each track's :class:`~ancsh.tracking.tracker.CategoryTracker` steps on its region's points
   (warm fits, the network every ``network_every``-th frame, carried correspondences in between). Every
   ``verify_every``-th network frame of a track is verified: the category template posed at the fit is rendered and
   compared with the depth (:func:`~ancsh.solvers.twin.compare_fit`); it must explain ``min_explained`` of the
   region's depth and see through at most ``max_see_through`` (``p_object`` is reported), else the track is not
   measured again before a fresh detection (on the next frame) re-initialises it; the tracker's own checks (inliers,
   the category's size range, residual, joint range) run on every frame, and a fit whose object is more than
   ``max_size_change`` times larger or smaller than the track's size so far is no measurement of it. An accepted fit
   is the measurement of the track's filter; a measurement far from the prediction is checked against the depth:
   where the category template posed at it explains the region better than at the prediction (explained less
   seen-through share, at least ``min_explained - max_see_through``) the filter restarts from it, else it is an
   outlier (the state coasts, and the tracker restarts warm from the filtered state).
3. **Detection.** ``ancsh predict``'s object list (:func:`~ancsh.learned.inference.predict.predict_depth`: isolation,
   every candidate verified), on the depth without the pixels of the tracks measured on this frame: on the first
   frame, every ``detect_every``-th frame, every ``redetect_every``-th frame while a track is missing, and after a
   failed verification. Detections are associated with tracks by an assignment problem
   (:func:`~ancsh.tracking.association.associate`: segment overlap and the distance of the root parts, gated; never
   farther than ``max_translation`` object diagonals);
   a matched track that is missing or far from its detection is re-initialised from the detection (not from its last
   state); an unmatched verified detection is a new track (*born*); one mostly inside a live track's pixels is not.
   An unpaired detection on a missing track's predicted pixels re-initialises that track.
4. **Ends.** A track without an accepted measurement for more than ``max_misses`` frames ends (short losses --
   occlusion, a few bad frames -- are bridged by the filter's prediction). Two tracks whose regions overlap by
   ``inside_share`` are one object: the older id keeps the more recently measured state, the other track ends.

Per track and frame a :class:`TrackRecord`: ``born``, ``tracked``, ``outlier`` (measured, not applied), ``coasting``
(no acceptable measurement: the prediction), ``reinitialised``; with the filtered state and its standard deviations.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field

import numpy as np

from ..geometry._checks import check_int, check_number
from ..geometry.boxes import OrientedBox
from ..geometry.rotations import geodesic_angle
from ..solvers.types import FitResult, Observation
from .association import associate
from .cold_fit import tracked_category
from .config import TrackerConfig
from .records import MultiFrame, TrackRecord
from .regions import support_height
from .state_filter import StateFilter, StateFilterConfig, filtered_fit

__all__ = ["MultiFrame", "MultiObjectTracker", "MultiTrackerConfig", "TrackRecord", "filtered_fit", "support_height"]


#: A track's size reference keeps this share of itself at each applied measurement (the rest is the measurement's
#: object diagonal): the tracker's first-stage fits may measure an object larger or smaller than its detection's
#: refined fit did, steadily; a fit that runs away from it frame by frame is refused.
SIZE_MEMORY = 0.8
#: The regions' tests run on every this-many-th pixel of each row and column (:meth:`MultiObjectTracker._regions`).
REGION_STRIDE = 2


def _default_tracker() -> TrackerConfig:
    # the category template's refinement costs seconds at each (re-)initialisation: not carried by default here
    return TrackerConfig(network_every=3, template_categories=())


@dataclass(frozen=True)
class MultiTrackerConfig:
    """Settings of :class:`MultiObjectTracker` (module docstring; validated on construction).

    Attributes
    ----------
    detect_every : int
        Frames between detections while every track is measured, ``>= 1``.
    redetect_every : int
        Frames between detections while a track is missing, ``>= 1``.
    max_misses : int
        A track ends after more frames than this without an accepted measurement, ``>= 0``.
    max_objects : int or None
        At most this many live tracks (``None``: every verified object).
    region_margin : float
        Growth of each part box for a track's region, object diagonals, ``>= 0``.
    support_clearance : float
        Points less than this above the track's support are not its own, object diagonals, ``>= 0``; at most
        ``max_clearance_m`` metres.
    max_clearance_m : float
    same_object_iou : float
        A detection whose mask overlaps a track's pixels this much (intersection over union) may be that track,
        ``(0, 1]``.
    gate_translation : float
        Or whose root part lies at most this many object diagonals from the track's, ``> 0``.
    max_translation : float
        And never one whose root part lies more than this many object diagonals from the track's (a touching neighbour
        of the same category is about one diagonal away), ``> 0``.
    reinit_rotation_deg : float
        A matched detection whose root rotation differs from the track's by more than this re-initialises it, ``> 0``.
    reinit_state : float
        Or whose joint states differ by more than this (radians; metres for prismatic joints), ``> 0``.
    inside_share : float
        A detection with at least this share of its pixels in live tracks' regions is no new object, ``(0, 1]``.
    max_size_change : float
        A fit whose object diagonal differs from the track's size so far (its detection's, then a running mean of its
        measurements, :data:`SIZE_MEMORY`) by more than this factor (either way) is no measurement of it (objects do
        not grow: a track on a wall or a table would), ``> 1``.
    verify_every : int
        A track's network frames between verifications (render-and-compare and ``p_object``), ``>= 0`` (0: never).
    min_explained, max_see_through : float
        The verification's bounds, in ``[0, 1]``: the share of the region's depth the category template posed at the
        fit explains (at least), and the share it says is seen through (at most) (:func:`~ancsh.solvers.twin.compare_fit`).
        A track was verified at its birth (``predict``'s checks, ``p_object`` among them); the check in the loop is for
        a model that no longer explains its pixels. (``p_object`` itself is reported, not used: it is calibrated on
        ``predict``'s fits of ``predict``'s segments, and a warm fit of a track's region drew 0.04 where ``predict``
        under the same mask drew 0.69, on a rendered laptop sequence.) Defaults chosen by hand on the rendered
        sequences of ``ancsh bench track-scenes`` (good laptop fits explain about 0.75, see through 0.2-0.4).
    num_points : int
        Points sampled per track and frame, ``>= 16``.
    tracker : TrackerConfig
        Every track's :class:`~ancsh.tracking.tracker.CategoryTracker` (default: the network every 3rd frame, no
        category template).
    filter : StateFilterConfig
    """

    detect_every: int = 60
    redetect_every: int = 10
    max_misses: int = 15
    max_objects: int | None = None
    region_margin: float = 0.15
    support_clearance: float = 0.02
    max_clearance_m: float = 0.008
    same_object_iou: float = 0.2
    gate_translation: float = 0.2
    max_translation: float = 0.5
    reinit_rotation_deg: float = 30.0
    reinit_state: float = np.deg2rad(30.0)
    inside_share: float = 0.5
    max_size_change: float = 1.4
    verify_every: int = 3
    min_explained: float = 0.4
    max_see_through: float = 0.6
    num_points: int = 1024
    tracker: TrackerConfig = field(default_factory=_default_tracker)
    filter: StateFilterConfig = field(default_factory=StateFilterConfig)

    def __post_init__(self):
        for name, lo in (("detect_every", 1), ("redetect_every", 1), ("max_misses", 0), ("verify_every", 0),
                         ("num_points", 16)):
            object.__setattr__(self, name, check_int(getattr(self, name), name, minimum=lo))
        if self.max_objects is not None:
            object.__setattr__(self, "max_objects", check_int(self.max_objects, "max_objects", minimum=1))
        for name in ("region_margin", "support_clearance", "max_clearance_m"):
            check_number(getattr(self, name), name, minimum=0.0)
        for name in ("same_object_iou", "inside_share"):
            check_number(getattr(self, name), name, minimum=0.0, maximum=1.0, lower_open=True)
        check_number(self.max_size_change, "max_size_change", minimum=1.0, lower_open=True)
        for name in ("gate_translation", "max_translation", "reinit_rotation_deg", "reinit_state"):
            check_number(getattr(self, name), name, minimum=0.0, lower_open=True)
        for name in ("min_explained", "max_see_through"):
            check_number(getattr(self, name), name, minimum=0.0, maximum=1.0)
        if not isinstance(self.tracker, TrackerConfig):
            raise ValueError(f"tracker: expected a TrackerConfig, got {type(self.tracker).__name__}")
        if not isinstance(self.filter, StateFilterConfig):
            raise ValueError(f"filter: expected a StateFilterConfig, got {type(self.filter).__name__}")


@dataclass
class _Track:
    """A live track: its tracker, filter and the last accepted fit (the model the filtered state poses)."""

    id: int
    tracker: object
    filter: StateFilter
    result: FitResult
    correspondences: object
    born: int
    diagonal: float
    mask: np.ndarray | None = None
    misses: int = 0
    network_frames: int = 0
    p_object: float | None = None
    suspect: bool = False  # its model failed the verification: only a detection restarts it
    size: float = 0.0  # the object's diagonal so far (metres): its detection's, then a running mean of measurements

    def model(self) -> FitResult:
        """The fitted model at the filtered state."""
        f = self.filter
        return filtered_fit(self.result, self.correspondences, f.R, f.translation, f.joint_states)


class MultiObjectTracker:
    """Tracks every object of a category through depth images (module docstring).

    Parameters
    ----------
    provider : LearnedProvider
        The category's network (shared by the detections and every track).
    intrinsics : Intrinsics
        Of every frame.
    category : str, Path or Category
        A name, spec file, built folder or loaded :class:`~ancsh.learned.inference.category.Category` (loaded once);
        it must have a convention.
    config : MultiTrackerConfig, optional
    seed : int
        Of the detections (``predict``'s seed), the point samples and the fits.
    """

    def __init__(self, provider, intrinsics, category, config: MultiTrackerConfig | None = None, *, seed: int = 0):
        from ..model.articulated import JointType

        if not hasattr(provider, "correspond"):
            raise ValueError("provider: expected a correspondence provider (with .correspond), got "
                             f"{type(provider).__name__}")
        self.provider = provider
        self._provider = _Remembering(provider)  # the tracks' provider: keeps its last inference for verification
        self.intrinsics = intrinsics
        #: The :class:`~ancsh.learned.inference.category.Category`, loaded once (every detection, verification and
        #: track uses it), and its name.
        self.category_info = tracked_category(category, provider)
        if self.category_info is None or self.category_info.convention is None:
            raise ValueError(f"category: {category!r} has no convention (its joints' types and ranges): give a "
                             "built-in name, a spec file or a built category folder")
        self.category = self.category_info.name
        self.config = MultiTrackerConfig() if config is None else config
        if not isinstance(self.config, MultiTrackerConfig):
            raise ValueError(f"config: expected a MultiTrackerConfig, got {type(self.config).__name__}")
        self.seed = check_int(seed, "seed", minimum=0)
        conv = self.category_info.convention
        self._joint_types = tuple(JointType(j.type).value for j in conv.joints)
        self._limits = conv.joint_limits
        self._tracks: list[_Track] = []
        self._next_id = 0
        self._index = 0
        self._last_detection = None
        self._plane_rng = np.random.default_rng(self.seed)
        self._detect_now = False  # a verification failed: detect on the next frame

    @property
    def joint_types(self) -> tuple:
        """``"revolute"`` / ``"prismatic"`` per joint of the category."""
        return self._joint_types

    @property
    def tracks(self) -> tuple:
        """Ids of the live tracks."""
        return tuple(t.id for t in self._tracks)

    def step(self, depth) -> MultiFrame:
        """Track one more depth image ``(H, W)`` (metres, 0 = no measurement)."""
        t0 = time.perf_counter()
        depth = np.asarray(depth, dtype=np.float64)
        if depth.shape != (self.intrinsics.height, self.intrinsics.width):
            raise ValueError(f"depth: expected ({self.intrinsics.height}, {self.intrinsics.width}) for the intrinsics, "
                             f"got {depth.shape}")
        index, self._index = self._index, self._index + 1
        cfg = self.config
        stages = {"regions": 0.0, "measure": 0.0, "verify": 0.0, "detect": 0.0}
        for tr in self._tracks:
            tr.filter.predict()
        t = time.perf_counter()
        regions = self._regions(depth)
        stages["regions"] = 1e3 * (time.perf_counter() - t)
        records = {}
        for tr in self._tracks:
            records[tr.id] = self._measure(tr, depth, regions[tr.id], index, stages)
        detected, detections = False, 0
        missing = any(tr.misses > 0 for tr in self._tracks)
        since = None if self._last_detection is None else index - self._last_detection
        if since is None or since >= cfg.detect_every or self._detect_now or (
                (missing or not self._tracks) and since >= cfg.redetect_every):
            self._detect_now = False
            t = time.perf_counter()
            detections = self._detect(depth, index, regions, records)
            detected = True
            self._last_detection = index
            stages["detect"] = 1e3 * (time.perf_counter() - t)
        merged = self._merge_duplicates({tr.id: records[tr.id].mask for tr in self._tracks if tr.id in records}, records)
        ended = merged + tuple(tr.id for tr in self._tracks if tr.misses > cfg.max_misses)
        self._tracks = [tr for tr in self._tracks if tr.misses <= cfg.max_misses]
        live = tuple(records[tr.id] for tr in self._tracks)
        return MultiFrame(index, live, ended, detected, detections, stages, time.perf_counter() - t0)

    # --- regions -------------------------------------------------------------------------------------------------

    def _regions(self, depth) -> dict:
        """Each live track's pixels (module docstring, item 1): ``{id: (H, W) bool}``. The tests run on every
        :data:`REGION_STRIDE`-th pixel of each row and column; each pixel with depth takes its block's verdict."""
        from ..data.render import project

        H, W = depth.shape
        intr = self.intrinsics
        cfg = self.config
        k = REGION_STRIDE
        coarse = depth[::k, ::k]
        best = np.full(coarse.shape, np.inf)
        owner = np.full(coarse.shape, -1, dtype=np.int64)
        for n, tr in enumerate(self._tracks):
            # where the object was last measured (the filter's output lags a moving part), else the prediction
            model = tr.result if tr.misses == 0 else tr.model()
            L = tr.diagonal
            margin = cfg.region_margin * L
            boxes = [OrientedBox(b.center, b.rotation, b.extents + 2 * margin) for b in model.boxes_cam]
            corners = np.concatenate([b.corners() for b in boxes])
            if np.any(corners[:, 2] <= 1e-3):
                continue  # behind the camera: nothing to measure
            uv = project(corners, intr)[0] / k
            u0, v0 = (int(max(np.floor(uv[:, i].min()), 0)) for i in (0, 1))
            u1 = int(min(np.ceil(uv[:, 0].max()) + 1, coarse.shape[1]))
            v1 = int(min(np.ceil(uv[:, 1].max()) + 1, coarse.shape[0]))
            if u0 >= u1 or v0 >= v1:
                continue
            z = coarse[v0:v1, u0:u1]
            vv, uu = np.nonzero(z > 0)
            if len(vv) == 0:
                continue
            d = z[vv, uu]
            P = np.stack([((uu + u0) * k - intr.cx) * d / intr.fx, ((vv + v0) * k - intr.cy) * d / intr.fy, d], axis=1)
            depth_in, in_model = np.full(len(P), np.inf), np.zeros(len(P), dtype=bool)
            for b, own in zip(boxes, model.boxes_cam):
                local = np.abs((P - b.center) @ b.rotation)
                depth_in = np.minimum(depth_in, (local / np.maximum(b.extents / 2, 1e-9)).max(axis=1))
                in_model |= np.all(local <= own.extents / 2, axis=1)
            inside = depth_in <= 1.0
            up = model.T_cam_npcs[self._root(tr)].rotation[:, 1]
            bottom = float(np.min(np.concatenate([b.corners() for b in model.boxes_cam]) @ up))
            clearance = min(cfg.support_clearance * L, cfg.max_clearance_m)
            height = support_height(P[inside], up, bottom, L, self._plane_rng, around=~in_model[inside])
            keep = inside.copy()
            keep[inside] = height > clearance
            rows, cols = vv[keep] + v0, uu[keep] + u0
            closer = depth_in[keep] < best[rows, cols]
            best[rows[closer], cols[closer]] = depth_in[keep][closer]
            owner[rows[closer], cols[closer]] = n
        full = np.repeat(np.repeat(owner, k, axis=0), k, axis=1)[:H, :W]
        full = np.where(depth > 0, full, -1)
        return {tr.id: full == n for n, tr in enumerate(self._tracks)}

    @staticmethod
    def _root(tr: _Track) -> int:
        return tr.correspondences.root_part

    # --- measurements --------------------------------------------------------------------------------------------

    def _measure(self, tr: _Track, depth, mask, index: int, stages: dict) -> TrackRecord:
        """Step the track's tracker on its pixels and filter the fit (module docstring, item 2)."""
        from ..learned.inference.candidate import depth_to_points
        from ..learned.inference.checks import object_diagonal

        cfg = self.config
        t = time.perf_counter()
        pixels = int(np.count_nonzero(mask))
        tr.mask = mask
        K = len(self._joint_types)
        nan = np.full(K, np.nan)
        if tr.suspect:
            tr.misses += 1
            return self._record(tr, "coasting", "its model failed the verification: waiting for a fresh detection",
                                "none", nan, pixels)
        if pixels < cfg.tracker.min_points:
            tr.misses += 1
            tr.tracker.reset()
            stages["measure"] += 1e3 * (time.perf_counter() - t)
            return self._record(tr, "coasting", f"{pixels} pixels in its region (occluded or out of view)", "none", nan,
                                pixels)
        points = depth_to_points(depth, self.intrinsics, mask=mask, num_points=cfg.num_points,
                                 rng=self.seed + 7919 * index + tr.id)[0]
        observation = Observation(points)
        frame = tr.tracker.step(observation)
        stages["measure"] += 1e3 * (time.perf_counter() - t)
        if not frame.ok:
            tr.misses += 1
            return self._record(tr, "coasting", frame.message, "none", nan, pixels)
        result = frame.result
        corr = tr.tracker.correspondences or tr.correspondences
        measured_size = object_diagonal(result.boxes_cam)
        size = measured_size / tr.size
        if not 1.0 / cfg.max_size_change <= size <= cfg.max_size_change:
            tr.misses += 1
            tr.tracker.reset()
            return self._record(tr, "coasting", f"the fit is {size:.2f} times the object's size so far "
                                f"(at most {cfg.max_size_change} either way): not this object", frame.source,
                                np.asarray(result.joint_states, dtype=np.float64), pixels)
        if frame.source == "network":
            tr.network_frames += 1
            if cfg.verify_every and tr.network_frames % cfg.verify_every == 0:
                t = time.perf_counter()
                comparison, p = self._evidence(result, corr, depth, mask, points)
                stages["verify"] += 1e3 * (time.perf_counter() - t)
                tr.p_object = p
                if comparison is not None and (comparison.explained < cfg.min_explained
                                               or comparison.see_through > cfg.max_see_through):
                    tr.misses += 1
                    tr.tracker.reset()
                    tr.suspect = True  # not measured again before a fresh detection re-initialises it
                    self._detect_now = True
                    return self._record(tr, "coasting", f"verification failed: the fitted model explains "
                                        f"{comparison.explained:.2f} of the region's depth (at least {cfg.min_explained}), "
                                        f"{comparison.see_through:.2f} seen through (at most {cfg.max_see_through}); "
                                        "waiting for a fresh detection", frame.source,
                                        np.asarray(result.joint_states, dtype=np.float64), pixels)
        states = np.asarray(result.joint_states, dtype=np.float64)
        root = corr.root_part
        T = result.T_cam_npcs[root]
        update = tr.filter.update(T.rotation, T.translation, states, _std(result))
        if not update.applied:  # an outlier: the depth decides between the measurement and the prediction
            t = time.perf_counter()
            predicted = tr.model()
            new, old = (self._explained(r, c, depth, mask) for r, c in ((result, corr), (predicted, tr.correspondences)))
            stages["verify"] += 1e3 * (time.perf_counter() - t)
            if new is not None and new >= cfg.min_explained - cfg.max_see_through and (old is None or new >= old):
                tr.filter.restart(T.rotation, T.translation, states, _std(result))
                tr.result, tr.correspondences, tr.misses = result, corr, 0
                return self._record(tr, "tracked", f"measurement {update.innovation:.1f} sigma from the prediction, "
                                    f"verified: it explains the depth better ({new:.2f} against "
                                    f"{old if old is not None else float('nan'):.2f}); "
                                    "the state restarts from it", frame.source, states, pixels)
            tr.tracker.start_from(observation, dataclasses.replace(predicted, inliers=result.inliers), corr)
            return self._record(tr, "outlier", f"measurement {update.innovation:.1f} sigma from the prediction, and the "
                                "prediction explains the depth better: not applied", frame.source, states, pixels)
        tr.result, tr.correspondences, tr.misses = result, corr, 0
        tr.size = (1.0 - SIZE_MEMORY) * measured_size + SIZE_MEMORY * tr.size
        message = "restarted from the measurement after outliers in a row" if update.restarted else frame.message
        return self._record(tr, "tracked", message, frame.source, states, pixels)

    def _explained(self, result, corr, depth, mask):
        """Share of ``mask``'s depth that the category template posed at ``result`` explains, less the share it says
        is seen through (render-and-compare, :func:`~ancsh.solvers.twin.compare_fit`); ``None`` where it cannot
        render."""
        from ..learned.inference.candidate import template_comparison

        comparison = template_comparison(result, corr, depth, self.intrinsics, mask, self.category_info)
        return None if comparison is None else float(comparison.explained) - float(comparison.see_through)

    def _evidence(self, result, corr, depth, mask, points):
        """Render-and-compare of a network frame's fit on ``mask`` and its ``p_object`` (the category's calibration, the
        network's segmentation margins of this frame): ``(DepthComparison or None, float or None)``."""
        from ..learned.inference.candidate import object_evidence
        from ..learned.inference.predict import part_quality

        last = self._provider.last
        prediction = last.prediction if last is not None and last.correspondences.num_points == len(points) else None
        quality = part_quality(result, points, corr, prediction)
        return object_evidence(result, corr, depth, self.intrinsics, mask, self.category_info, quality, self.provider,
                               points)

    def _record(self, tr: _Track, status, message, source, measured, pixels) -> TrackRecord:
        f = tr.filter
        if status in ("coasting", "outlier"):
            f.coast()
        return TrackRecord(tr.id, status, message, source, tr.model(), f.joint_states, f.joint_states_std,
                           np.asarray(measured, dtype=np.float64), f.translation_std, f.rotation_std, pixels, tr.p_object,
                           tr.misses, tr.mask)

    # --- detection -----------------------------------------------------------------------------------------------

    def _detect(self, depth, index: int, regions: dict, records: dict) -> int:
        """``predict``'s verified objects, associated with the tracks (module docstring, item 3); new tracks born,
        matched tracks re-initialised where needed; returns the number of verified detections."""
        from ..learned.inference.checks import object_diagonal
        from ..learned.inference.predict import predict_depth

        cfg = self.config
        rest = depth.copy()  # the measured tracks' pixels are taken: predict looks for the other objects
        for tr in self._tracks:
            if tr.misses == 0 and regions.get(tr.id) is not None:
                rest[regions[tr.id]] = 0.0
        pred = predict_depth(rest, self.intrinsics, self.category_info, provider=self.provider, seed=self.seed,
                             max_objects=cfg.max_objects)
        found = [o for o in (pred.objects or (pred,)) if o.result.ok and o.correspondences is not None and o.mask is not None]
        if not found:
            return 0
        dets = []
        for o in found:
            root = o.correspondences.root_part
            dets.append((o, o.result.T_cam_npcs[root], object_diagonal(o.result.boxes_cam)))
        cost = np.full((len(self._tracks), len(dets)), np.inf)
        for i, tr in enumerate(self._tracks):
            mask = regions.get(tr.id)
            T = tr.model().T_cam_npcs[self._root(tr)]
            for j, (o, Td, L) in enumerate(dets):
                inter = np.count_nonzero(mask & o.mask) if mask is not None else 0
                iou = inter / max(np.count_nonzero(mask | o.mask), 1) if mask is not None else 0.0
                dist = float(np.linalg.norm(Td.translation - T.translation)) / max(L, tr.diagonal)
                if dist <= cfg.max_translation and (iou >= cfg.same_object_iou or dist <= cfg.gate_translation):
                    cost[i, j] = (1.0 - iou) + dist
        pairs = associate(cost)
        matched = {j for _, j in pairs}
        for i, j in pairs:
            tr, (o, Td, L) = self._tracks[i], dets[j]
            f = tr.filter
            far = (np.rad2deg(geodesic_angle(Td.rotation, f.R)) > cfg.reinit_rotation_deg
                   or np.any(np.abs(np.asarray(o.result.joint_states) - f.joint_states) > cfg.reinit_state))
            if tr.misses > 0 or far:
                self._start(tr, o, L)
                records[tr.id] = self._record(tr, "reinitialised", "re-initialised from a verified detection"
                                              + (" far from its state" if far and tr.misses == 0 else ""), "detection",
                                              np.asarray(o.result.joint_states, dtype=np.float64), int(o.mask.sum()))
        tracked = np.zeros(depth.shape, dtype=bool)
        for m in regions.values():
            tracked |= m
        for j, (o, Td, L) in enumerate(dets):
            if j in matched:
                continue
            if cfg.max_objects is not None and len(self._tracks) >= cfg.max_objects:
                break
            if np.count_nonzero(o.mask & tracked) >= cfg.inside_share * max(np.count_nonzero(o.mask), 1):
                continue  # a piece of an object already tracked
            lost = self._missing_track_at(o, regions, paired={i for i, _ in pairs})
            if lost is not None:  # where a missing track is predicted: that object, back
                self._start(lost, o, L)
                records[lost.id] = self._record(lost, "reinitialised", "re-initialised from a verified detection on "
                                                "its predicted pixels", "detection",
                                                np.asarray(o.result.joint_states, dtype=np.float64), int(o.mask.sum()))
                tracked |= o.mask
                continue
            tr = _Track(self._next_id, None, None, o.result, o.correspondences, index, L)
            self._next_id += 1
            self._start(tr, o, L)
            self._tracks.append(tr)
            tracked |= o.mask
            records[tr.id] = self._record(tr, "born", "a verified detection", "detection",
                                          np.asarray(o.result.joint_states, dtype=np.float64), int(o.mask.sum()))
        return len(dets)

    def _missing_track_at(self, det, regions: dict, paired: set):
        """The missing track (not paired with a detection this frame) on whose predicted pixels ``det`` lies (at least
        ``same_object_iou`` of the detection's mask) with its root part within ``max_translation`` object diagonals,
        the most overlapped one; ``None`` if none."""
        from ..learned.inference.checks import object_diagonal

        best, best_share = None, self.config.same_object_iou
        n = max(int(np.count_nonzero(det.mask)), 1)
        root = det.result.T_cam_npcs[det.correspondences.root_part].translation
        for i, tr in enumerate(self._tracks):
            region = regions.get(tr.id)
            if i in paired or tr.misses == 0 or region is None:
                continue
            L = max(object_diagonal(det.result.boxes_cam), tr.diagonal)
            if np.linalg.norm(root - tr.model().T_cam_npcs[self._root(tr)].translation) > self.config.max_translation * L:
                continue
            share = np.count_nonzero(region & det.mask) / n
            if share >= best_share:
                best, best_share = tr, share
        return best

    def _merge_duplicates(self, regions: dict, records: dict) -> tuple:
        """Two live tracks on one object (their regions overlapping by ``inside_share`` of the smaller): the younger
        one's state goes to the older id, the younger ends. Returns the ended ids."""
        ended = []
        for a in list(self._tracks):
            for b in list(self._tracks):
                if a is b or a.id > b.id or b not in self._tracks or a not in self._tracks:
                    continue
                ra, rb = regions.get(a.id), regions.get(b.id)
                if ra is None or rb is None:
                    continue
                small = max(min(int(ra.sum()), int(rb.sum())), 1)
                if np.count_nonzero(ra & rb) < self.config.inside_share * small:
                    continue
                keep, drop = a, b  # the older id stays; the state of the one measured more recently
                if drop.misses < keep.misses:
                    keep.tracker, keep.filter, keep.result, keep.correspondences = (drop.tracker, drop.filter,
                                                                                   drop.result, drop.correspondences)
                    keep.diagonal, keep.misses, keep.mask, keep.p_object = (drop.diagonal, drop.misses, drop.mask,
                                                                            drop.p_object)
                    if drop.id in records:
                        records[keep.id] = dataclasses.replace(records[drop.id], id=keep.id, message=(
                            records[drop.id].message + f"; merged with track {drop.id}"))
                self._tracks.remove(drop)
                records.pop(drop.id, None)
                ended.append(drop.id)
        return tuple(ended)

    def _start(self, tr: _Track, det, diagonal: float) -> None:
        """(Re)start ``tr`` from the detection ``det`` (a :class:`~ancsh.learned.inference.predict.DepthPrediction`)."""
        from .tracker import CategoryTracker

        result, corr = det.result, det.correspondences
        if tr.tracker is None:
            tr.tracker = CategoryTracker(self._provider, self.config.tracker, category=self.category_info,
                                         rng=self.seed + 104729 * tr.id)
        tr.tracker.start_from(Observation(det.points_cam), result, corr)
        tr.filter = StateFilter(self._joint_types, self._limits, self.config.filter)
        root = corr.root_part
        T = result.T_cam_npcs[root]
        tr.filter.update(T.rotation, T.translation, result.joint_states, _std(result))
        tr.result, tr.correspondences, tr.diagonal, tr.size = result, corr, float(diagonal), float(diagonal)
        tr.misses, tr.mask, tr.suspect = 0, det.mask, False
        tr.p_object = det.p_object


class _Remembering:
    """A correspondence provider that keeps its last :class:`~ancsh.learned.inference.provider.Inference` (``last``),
    so that a network frame's verification reads the network's segmentation margins without a second pass; every
    other attribute is the wrapped provider's."""

    def __init__(self, provider):
        self._wrapped = provider
        self.last = None

    def correspond(self, observation, **options):
        if hasattr(self._wrapped, "infer"):
            self.last = self._wrapped.infer(observation, **options)
            return self.last.correspondences
        self.last = None
        return self._wrapped.correspond(observation, **options)

    def __getattr__(self, name):
        return getattr(self._wrapped, name)


def _std(result) -> np.ndarray | None:
    from .records import joint_state_std

    return joint_state_std(result)
