"""The work behind ``ancsh serve``, without HTTP: :class:`PredictionService` keeps the categories' networks loaded
and answers predict and track-step requests with the same JSON as ``ancsh predict --out`` and ``ancsh track``.

One request is worked on at a time (a lock around the models: the predictions of parallel requests do not interleave
and each is what ``predict`` gives for its inputs); health and version answer at once. The loaded providers are kept
per (category, refinement, seed), the least recently used dropped beyond ``max_providers``; tracking sessions per
name, the least recently used dropped beyond ``max_sessions``.
"""

from __future__ import annotations

import threading
import time
from collections import OrderedDict
from pathlib import Path

from .requests import PathPolicy, RequestError, parse_predict, parse_track

__all__ = ["PredictionService"]

SCHEMA = "ancsh.prediction/2"
TRACK_SCHEMA = "ancsh.track/1"
#: A session runs the network on every this many frames, as ``ancsh track`` does by default (``-k 3``).
TRACK_NETWORK_EVERY = 3


class PredictionService:
    """Loaded networks and tracking sessions behind the service's endpoints.

    Parameters
    ----------
    root : str or Path, optional
        The folder requests may read files from (``None``: images only as bytes).
    categories : sequence of str
        Categories whose networks are loaded at start (others load on their first request).
    device : str
        Torch device of the networks (``"cpu"``).
    max_providers, max_sessions : int
        How many loaded providers and tracking sessions are kept.
    """

    def __init__(self, *, root=None, categories=(), device: str = "cpu", max_providers: int = 16,
                 max_sessions: int = 32):
        if root is not None and not Path(root).is_dir():
            raise ValueError(f"root: {root} is not a folder")
        for name, value in (("max_providers", max_providers), ("max_sessions", max_sessions)):
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ValueError(f"{name}: expected a positive integer, got {value!r}")
        self.policy = PathPolicy(None if root is None else Path(root).resolve())
        self.device = device
        self.max_providers, self.max_sessions = max_providers, max_sessions
        self._lock = threading.Lock()
        self._providers: OrderedDict = OrderedDict()
        self._categories: dict = {}  # name -> Category, loaded once (spec, calibrations, template)
        self._sessions: OrderedDict = OrderedDict()
        self._started = time.time()
        self.counts = {"predict": 0, "track": 0, "refused": 0, "failed": 0}
        for category in categories:
            self._provider(category, "auto", 0)

    # -- the endpoints ---------------------------------------------------------------------------------------
    def health(self) -> dict:
        """``{"status": "ok", ...}``: uptime, loaded categories, sessions and request counts."""
        return {"status": "ok", "uptime_s": round(time.time() - self._started, 3),
                "loaded": sorted({key[0] for key in self._providers}), "sessions": len(self._sessions),
                "requests": dict(self.counts)}

    def version(self) -> dict:
        """The package version and the result schemas."""
        from .._version import __version__

        return {"ancsh_version": __version__, "schemas": {"predict": SCHEMA, "track": TRACK_SCHEMA}}

    def predict(self, body) -> dict:
        """``/predict``: the result of ``ancsh predict`` for the request's depth (``docs/serve.md``)."""
        request = parse_predict(body, self.policy)
        with self._lock:
            self.counts["predict"] += 1
            return self._predict(request)

    def track(self, body) -> dict:
        """``/track``: one frame of the session's track, the record of ``ancsh track`` (``ancsh.track/1``)."""
        from ..tracking.stream import track_depth

        request = parse_track(body, self.policy)
        frame = request.frame
        with self._lock:
            self.counts["track"] += 1
            if request.reset:
                self._sessions.pop(request.session, None)
            session = self._sessions.get(request.session)
            if session is not None and session["category"] != frame.category:
                raise RequestError(409, f"category: session {request.session!r} tracks {session['category']!r}, not "
                                        f"{frame.category!r}; reset it or use another session")
            if session is not None and session["intrinsics"] != frame.intrinsics:
                raise RequestError(409, f"intrinsics: session {request.session!r} was started with other intrinsics; "
                                        "reset it or use another session")
            if session is None:
                session = self._new_session(request.session, frame)
            self._sessions.move_to_end(request.session)
            record = track_depth(frame.depth, frame.intrinsics, session["tracker"], session["frames"], mask=frame.mask,
                                 category=self._category(frame.category), isolate=frame.isolate,
                                 max_depth=frame.max_depth,
                                 num_points=frame.points, seed=frame.seed)
            session["frames"] += 1
            return {"schema": TRACK_SCHEMA, "session": request.session, **record}

    def end_track(self, body) -> dict:
        """``/track/end``: forget a session (``{"session": name}``); whether it existed."""
        if not isinstance(body, dict) or not isinstance(body.get("session"), str):
            raise RequestError(400, "session: expected {\"session\": name}")
        with self._lock:
            return {"session": body["session"], "ended": self._sessions.pop(body["session"], None) is not None}

    # -- the models ------------------------------------------------------------------------------------------
    def _category(self, name: str):
        """The :class:`~ancsh.learned.inference.category.Category` of ``name``, loaded once for the service's life; a
        404 for a name that is no category or has no network."""
        from ..learned.inference.category import load_category
        from ..learned.network.weights import missing_weights_error

        if name not in self._categories:
            try:
                category = load_category(name)
            except (FileNotFoundError, ValueError) as exc:
                raise RequestError(404, f"category: {exc}") from None
            if not category.weights_path().is_file():
                raise RequestError(404, f"category: {missing_weights_error(category.name)}")
            self._categories[name] = category
        return self._categories[name]

    def _provider(self, category: str, refine: str | None, seed: int):
        """The provider ``predict_depth`` would make for these options (``refine`` ``None``: the one ``ancsh track``
        makes), loaded once; a 404 for a category without shipped weights."""
        from ..learned.inference.predict import make_provider

        key = (category, None if refine is None else refine == "network", seed)
        if key not in self._providers:
            loaded = self._category(category)
            if refine is None:
                from ..learned.inference.provider import LearnedProvider

                self._providers[key] = LearnedProvider(loaded.weights_path(), seed=seed, device=self.device,
                                                       category=loaded)
            else:
                self._providers[key] = make_provider(loaded, seed=seed, refine=refine, device=self.device)
            while len(self._providers) > self.max_providers:
                self._providers.popitem(last=False)
        self._providers.move_to_end(key)
        return self._providers[key]

    def _predict(self, request) -> dict:
        from ..data.isolate import ObjectHint
        from ..learned.inference.predict import predict_depth

        hint = None
        if request.pixel is not None or request.box is not None:
            try:
                hint = ObjectHint(pixel=request.pixel, box=request.box)
            except ValueError as exc:
                raise RequestError(400, str(exc)) from None
        provider = self._provider(request.category, request.refine, request.seed)
        extra = {} if request.hypotheses is None else {"hypotheses": request.hypotheses}
        try:
            pred = predict_depth(request.depth, request.intrinsics, self._category(request.category), mask=request.mask,
                                 max_depth=request.max_depth, provider=provider, formulation=request.formulation,
                                 num_points=request.points, seed=request.seed, isolate=request.isolate, hint=hint,
                                 refine=request.refine, max_objects=request.max_objects, **extra)
        except ValueError as exc:  # the inputs' fault (a hint outside the image, a depth in millimetres)
            raise RequestError(400, str(exc)) from None
        data = pred.to_json()
        data["input"] = {**request.source, "intrinsics": request.intrinsics.to_json(), "max_depth": request.max_depth,
                         "seed": request.seed, "pixel": None if request.pixel is None else list(request.pixel),
                         "box": None if request.box is None else list(request.box), "isolate": request.isolate}
        return data

    def _new_session(self, name: str, frame) -> dict:
        from ..tracking.tracker import CategoryTracker, TrackerConfig

        provider = self._provider(frame.category, None, frame.seed)  # as ancsh track makes it
        tracker = CategoryTracker(provider, TrackerConfig(network_every=TRACK_NETWORK_EVERY),
                                  category=self._category(frame.category), rng=frame.seed)
        self._sessions[name] = {"category": frame.category, "intrinsics": frame.intrinsics, "tracker": tracker,
                                "frames": 0}
        while len(self._sessions) > self.max_sessions:
            self._sessions.popitem(last=False)
        return self._sessions[name]
