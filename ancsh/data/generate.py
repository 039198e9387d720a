"""Frame generation: instances, joint states, viewpoints, rendering, noise, points, ground truth.

Every frame is a pure function of the :class:`GenerationConfig` and its dataset index:
its random stream is seeded by :func:`frame_seed` ``(config.seed, index)``. It picks an
instance of the split, draws joint states uniformly within the limits and a viewpoint of
the category (:mod:`.render`), renders depth and part ids, rejects the view when a part
is (nearly) invisible and redraws state and view, applies sensor noise (:mod:`.noise`),
samples ``num_points`` back-projected pixels and computes the ANCSH ground truth.

:func:`generate_dataset` writes the frames into HDF5 shards (:mod:`.dataset`) with a
pool of workers (:mod:`ancsh.executors`: local processes or a Ray cluster; the frames do not
depend on which). Shards are written atomically; running it again on the same directory
verifies and skips complete shards, regenerates damaged or missing ones and produces
identical frames, so an interrupted run resumes where it stopped.
"""

from __future__ import annotations

import json
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from ..geometry._checks import check_int, check_number
from ..geometry.transforms import Sim3
from .dataset import CorruptShardError, Frame, ShardReader, write_shard
from .noise import DepthNoise, apply_noise
from .render import Intrinsics, ModelRenderer, sample_points, sample_viewpoint, viewpoint_range
from .sequences import SequenceMotion, SequencePlan, plan_sequence

__all__ = [
    "FrameGenerator",
    "FrameRejected",
    "GenerationConfig",
    "GenerationReport",
    "frame_seed",
    "generate_dataset",
    "shard_name",
]


class FrameRejected(RuntimeError):
    """No acceptable view was found within ``max_attempts`` draws."""


@dataclass(frozen=True)
class GenerationConfig:
    """What to generate (everything that determines the frames).

    Attributes
    ----------
    category : str or None
        A category with a convention (:data:`ancsh.data.conventions.CONVENTIONS`; a spec file or category
        folder is registered and replaced by its name); ``None`` with ``urdf``. A category without a
        procedural generator (:data:`ancsh.data.procedural.CATEGORIES`) renders its imported objects only
        (``real_fraction`` 1; ``real`` by default a built category folder's ``catalog.json``).
    split : str
        ``"train"`` or ``"test"`` instances (procedural and real).
    real : str or None
        A catalog of imported real objects (:mod:`.catalog`; ``"builtin"`` = the shipped one)
        whose objects of ``category`` and ``split`` join the procedural instances.
    real_fraction : float
        With ``real``: probability that a frame shows a real object (1 = real objects only).
        When the split has no real object of the category, every frame is procedural.
    urdf : str or None
        Path of a URDF object (instead of a procedural category).
    seed : int
        Base seed of the frames' random streams, ``>= 0``.
    shard_size : int
        Frames per shard (the last shard may hold fewer).
    num_points : int
        Points sampled per frame.
    intrinsics : Intrinsics
    noise : DepthNoise
        ``DepthNoise.off()`` for exact depth.
    min_part_pixels : int
        A view is rejected when a part shows on fewer pixels than this ...
    min_part_fraction : float
        ... or on less than this fraction of the object's pixels ...
    min_visibility : float
        ... or when its visible-area ratio is below this.
    max_attempts : int
        Redraws of joint state and view before :class:`FrameRejected`.
    sequence : SequenceMotion or None
        ``None``: independent frames. Otherwise frames form sequences of ``sequence.length``
        (:mod:`.sequences`): frame ``i`` is time ``i % length`` of sequence ``i // length``.
    real_split : str or None
        With ``real``: whose real objects join: ``None`` (the default) those of ``split``, ``"all"`` every
        imported object of the category, train and test (an evaluation on every real object there is; the
        training objects were seen in training).
    """

    category: str | None = None
    split: str = "train"
    urdf: str | None = None
    real: str | None = None
    real_fraction: float = 0.0
    seed: int = 0
    shard_size: int = 500
    num_points: int = 1024
    intrinsics: Intrinsics = field(default_factory=Intrinsics)
    noise: DepthNoise = field(default_factory=DepthNoise)
    min_part_pixels: int = 30
    min_part_fraction: float = 0.02
    min_visibility: float = 0.0
    max_attempts: int = 100
    sequence: SequenceMotion | None = None
    real_split: str | None = None

    def __post_init__(self):
        if self.sequence is not None and not isinstance(self.sequence, SequenceMotion):
            raise ValueError(f"sequence: expected a SequenceMotion or None, got {type(self.sequence).__name__}")
        if (self.category is None) == (self.urdf is None):
            raise ValueError("category: give exactly one of a procedural category and a URDF path")
        if self.urdf is None:
            from .conventions import resolve_category
            from .procedural import CATEGORIES
            from .procedural.registry import split_seeds

            object.__setattr__(self, "category", resolve_category(self.category))
            split_seeds(self.split)  # validates the split
            if self.category not in CATEGORIES:
                self._real_only()
        else:
            object.__setattr__(self, "urdf", str(Path(self.urdf).resolve()))
            if not Path(self.urdf).is_file():
                raise FileNotFoundError(f"urdf: no such file {self.urdf}")
        for name, lo in (("seed", 0), ("shard_size", 1), ("num_points", 1), ("min_part_pixels", 0), ("max_attempts", 1)):
            object.__setattr__(self, name, check_int(getattr(self, name), name, minimum=lo))
        if self.real is not None and self.urdf is not None:
            raise ValueError("real: real catalog objects mix with a procedural category, not with a URDF")
        if self.real is None and self.real_fraction != 0.0:
            raise ValueError("real_fraction: needs a real catalog (real=...)")
        if self.real_split not in (None, "all"):
            raise ValueError(f"real_split: expected None (the split's real objects) or 'all', got {self.real_split!r}")
        if self.real_split is not None and self.real is None:
            raise ValueError("real_split: needs a real catalog (real=...)")
        for name in ("min_part_fraction", "min_visibility", "real_fraction"):
            v = check_number(getattr(self, name), name, minimum=0.0, maximum=1.0)
            object.__setattr__(self, name, v)
        if not isinstance(self.intrinsics, Intrinsics):
            raise ValueError(f"intrinsics: expected Intrinsics, got {type(self.intrinsics).__name__}")
        if not isinstance(self.noise, DepthNoise):
            raise ValueError(f"noise: expected DepthNoise (DepthNoise.off() for none), got {type(self.noise).__name__}")

    @property
    def name(self) -> str:
        """Short dataset name: the category or the URDF object's folder/file name."""
        if self.urdf is not None:
            p = Path(self.urdf)
            return p.parent.name if p.stem in ("mobility", "model") else p.stem
        if self.real is not None:
            return f"{self.category}_{'real' if self.real_fraction >= 1.0 else 'mixed'}"
        return self.category

    def _real_only(self) -> None:
        """A category without a procedural generator shows its imported objects only: its own catalog (a built
        category folder's ``catalog.json``) unless ``real`` names one, in every frame."""
        from .conventions import category_folder

        folder = category_folder(self.category)
        if self.real is None and folder is not None and (folder / "catalog.json").is_file():
            object.__setattr__(self, "real", str(folder / "catalog.json"))
        if self.real_fraction == 0.0 and self.real is not None:
            object.__setattr__(self, "real_fraction", 1.0)
        if self.real is None or self.real_fraction < 1.0:
            raise ValueError(f"category: {self.category!r} has no procedural generator (a category from a spec "
                             "file): its frames show its imported objects only; give real=CATALOG with real_fraction 1 "
                             "(--real CATALOG), or build the category into a folder with its catalog.json")

    @property
    def has_generator(self) -> bool:
        """Whether the category has a procedural generator (a spec-only category renders its imported objects)."""
        from .procedural import CATEGORIES

        return self.category in CATEGORIES

    def to_json(self) -> str:
        """Canonical JSON of every setting (stored in each shard, compared on resume)."""
        d = asdict(self)
        d["intrinsics"] = self.intrinsics.to_json()
        d["noise"] = json.loads(self.noise.to_json())
        if self.sequence is None:  # single-frame datasets keep the settings they were written with
            del d["sequence"]
        if self.real_split is None:  # as datasets written before the setting existed
            del d["real_split"]
        else:
            d["sequence"] = self.sequence.to_dict()
        if self.urdf is None and self.has_generator:  # procedural shapes depend on the generators' version
            from .procedural import generator_version

            d["generator_version"] = generator_version(self.category)
        return json.dumps(d, sort_keys=True)


def frame_seed(base_seed: int, index: int) -> int:
    """Seed (``0 <= seed < 2**63``) of frame ``index``'s random stream."""
    state = np.random.SeedSequence([int(base_seed), int(index)]).generate_state(1, np.uint64)[0]
    return int(state >> np.uint64(1))


class FrameGenerator:
    """Generates frames of one :class:`GenerationConfig`, caching models and renderers.

    Parameters
    ----------
    config : GenerationConfig
    """

    def __init__(self, config: GenerationConfig):
        if not isinstance(config, GenerationConfig):
            raise ValueError(f"config: expected GenerationConfig, got {type(config).__name__}")
        self.config = config
        self._cache: dict = {}
        self._plans: dict = {}
        self._real: tuple = ()
        if config.urdf is not None:
            self._seeds = (-1,)
        else:
            from .procedural import instance_seeds

            self._seeds = tuple(instance_seeds(config.category, config.split)) if config.has_generator else ()
            if config.real is not None:
                from .catalog import load_catalog

                catalog = load_catalog(None if config.real == "builtin" else config.real)
                self._real = catalog.instances(config.category, None if config.real_split == "all" else config.split)
        self._num_procedural = len(self._seeds)
        if config.urdf is None and not config.has_generator and not self._real:
            raise ValueError(f"real: the catalog {config.real!r} holds no {config.category} object in the "
                             f"{config.split} split, and the category has no procedural generator: nothing to render")
        self._seeds = self._seeds + (-1,) * len(self._real)

    @property
    def real_instances(self) -> tuple:
        """The imported real objects among the instances (indices after the procedural ones)."""
        return self._real

    @property
    def num_instances(self) -> int:
        return len(self._seeds)

    def instance(self, index: int):
        """``(model, renderer)`` of instance ``index`` (cached)."""
        if index not in self._cache:
            cfg = self.config
            if cfg.urdf is not None:
                from .urdf import load_urdf

                model = load_urdf(cfg.urdf)
            elif index >= self._num_procedural:
                model = self._real[index - self._num_procedural].model()
            else:
                from .procedural import load_instance

                model = load_instance(cfg.category, cfg.split, int(index))
            missing = [p.name for p in model.parts if p.mesh is None]
            if missing:
                where = cfg.urdf if cfg.urdf is not None else model.name
                raise ValueError(f"{where}: part(s) {missing} have no mesh; ANCSH ground truth needs every part's surface")
            self._cache[index] = (model, ModelRenderer(model))
        return self._cache[index]

    @property
    def category(self) -> str:
        if self.config.category is not None:
            return self.config.category
        model, _ = self.instance(0)
        return model.category or "urdf"

    def _viewpoints(self, model):
        cat = self.config.category or model.category
        from .conventions import CONVENTIONS

        return viewpoint_range(cat if cat in CONVENTIONS else None)

    def accept(self, part_pixels: np.ndarray, visibility: np.ndarray) -> bool:
        """Whether a view shows every part enough (see :class:`GenerationConfig`)."""
        cfg = self.config
        total = part_pixels.sum()
        return bool(
            total > 0
            and np.all(part_pixels >= cfg.min_part_pixels)
            and np.all(part_pixels >= cfg.min_part_fraction * total)
            and np.all(visibility >= cfg.min_visibility)
        )

    def frame(self, index: int, *, keep_depth: bool = False) -> Frame:
        """Frame ``index`` of the dataset (deterministic).

        ``keep_depth=True`` also returns the noisy depth image the points were sampled from
        (``Frame.depth``; the input of ``ancsh predict``), at no extra cost. With
        ``config.sequence`` the frame is time ``index % length`` of sequence ``index // length``
        (:meth:`sequence_plan`).
        """
        cfg = self.config
        seed = frame_seed(cfg.seed, index)
        rng = np.random.default_rng(seed)
        if cfg.sequence is not None:
            seq, t = cfg.sequence.split(index)
            plan = self.sequence_plan(seq)
            model, renderer = self.instance(plan.instance)
            q, T_cam_base = plan.joint_states(t), plan.camera(t)
            view = renderer.render(q, T_cam_base, cfg.intrinsics, visibility=True)
            return self._finish(index, seed, rng, plan.instance, q, T_cam_base, view, keep_depth, seq, t)
        inst = self._draw_instance(rng)
        model, renderer = self.instance(inst)
        vr = self._viewpoints(model)
        for _ in range(cfg.max_attempts):
            q = model.random_states(rng)
            T_cam_base = sample_viewpoint(vr, rng, model, q)
            view = renderer.render(q, T_cam_base, cfg.intrinsics, visibility=True)
            if self.accept(view.part_pixels(model.num_parts), view.visibility):
                break
        else:
            raise FrameRejected(
                f"frame {index}: no view of {model.name!r} showed every part within {cfg.max_attempts} attempts "
                f"(min_part_pixels={cfg.min_part_pixels}, min_part_fraction={cfg.min_part_fraction})"
            )
        return self._finish(index, seed, rng, inst, q, T_cam_base, view, keep_depth)

    def _draw_instance(self, rng) -> int:
        cfg = self.config
        if self._real and cfg.real_fraction > 0:  # an extra draw only for mixed data: procedural frames stay as they were
            if cfg.real_fraction >= 1.0 or rng.random() < cfg.real_fraction:
                return self._num_procedural + int(rng.integers(len(self._real)))
            return int(rng.integers(self._num_procedural))
        return int(rng.integers(self._num_procedural))

    def sequence_plan(self, sequence: int) -> SequencePlan:
        """The motion of sequence ``sequence`` (cached; see :mod:`.sequences`).

        Its stream is seeded by ``(config.seed, sequence)`` apart from the frames' streams; a plan
        is drawn again until enough of its checked frames show every part.
        """
        cfg = self.config
        motion = cfg.sequence
        if motion is None:
            raise ValueError("sequence: this configuration generates single frames (config.sequence is None)")
        if sequence in self._plans:
            return self._plans[sequence]
        rng = np.random.default_rng(np.random.SeedSequence([int(cfg.seed), int(sequence), 0x5E0]))
        inst = self._draw_instance(rng)
        model, renderer = self.instance(inst)
        vr = self._viewpoints(model)
        times = np.unique(np.linspace(0, motion.length - 1, motion.checks).round().astype(int))
        for _ in range(motion.max_attempts):
            plan = plan_sequence(model, inst, vr, motion, rng)
            ok = 0
            for t in times:
                view = renderer.render(plan.joint_states(t), plan.camera(t), cfg.intrinsics, visibility=True)
                ok += self.accept(view.part_pixels(model.num_parts), view.visibility)
            if ok >= motion.min_accepted * len(times):
                break
        else:
            raise FrameRejected(f"sequence {sequence}: no camera path and joint cycles of {model.name!r} showed every "
                                f"part in {motion.min_accepted:.0%} of the checked frames within {motion.max_attempts} draws")
        if len(self._plans) > 8:
            self._plans.clear()
        self._plans[sequence] = plan
        return plan

    def _finish(self, index, seed, rng, inst, q, T_cam_base, view, keep_depth, sequence=-1, time_index=-1) -> Frame:
        """Noise, point sampling and ground truth of a rendered view."""
        from ..model.canonical import ancsh_ground_truth

        cfg = self.config
        model, _ = self.instance(inst)
        depth = apply_noise(view.depth, cfg.noise, rng)
        points, labels, _ = sample_points(depth, view.part_ids, cfg.intrinsics, cfg.num_points, rng)
        gt = ancsh_ground_truth(model, q, T_cam_base, points, labels)
        return Frame(
            points=points,
            gt=gt,
            intrinsics=cfg.intrinsics,
            T_cam_base=Sim3(T_cam_base.rotation, T_cam_base.translation),
            visibility=view.visibility,
            part_pixels=view.part_pixels(model.num_parts),
            joint_states_abs=np.asarray(q, dtype=np.float64),
            category=self.config.category or (model.category or "urdf"),
            instance=model.name,
            instance_index=inst,
            instance_seed=int(self._seeds[inst]),
            frame_index=int(index),
            seed=seed,
            part_names=tuple(model.part_names),
            joint_names=tuple(j.name for j in model.joints),
            depth=depth if keep_depth else None,
            sequence_index=int(sequence),
            time_index=int(time_index),
        )


# --------------------------------------------------------------------------------------
# datasets
# --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class GenerationReport:
    """Outcome of :func:`generate_dataset`.

    Attributes
    ----------
    out_dir : Path
    paths : tuple of Path
        All shards of the dataset, in order.
    written : tuple of int
        Shards generated by this run (new ones and replacements).
    skipped : tuple of int
        Complete, verified shards kept from an earlier run.
    replaced : tuple of (int, str)
        Shards that existed but were damaged or covered other frames, with the reason.
    frames_generated : int
    seconds : float
        Wall time.
    """

    out_dir: Path
    paths: tuple
    written: tuple
    skipped: tuple
    replaced: tuple
    frames_generated: int
    seconds: float

    @property
    def frames_per_second(self) -> float:
        return self.frames_generated / self.seconds if self.seconds > 0 else float("nan")


def shard_name(config: GenerationConfig, shard: int) -> str:
    """File name of shard ``shard``: ``<name>_<split>_<shard:05d>.h5``."""
    split = config.split if config.urdf is None else "urdf"
    return f"{config.name}_{split}_{shard:05d}.h5"


def _shard_ranges(frames: int, shard_size: int) -> list[tuple[int, int]]:
    return [(s, min(s + shard_size, frames)) for s in range(0, frames, shard_size)]


def _check_existing(path: Path, config_json: str, start: int, stop: int, overwrite: bool) -> str | None:
    """``None`` when ``path`` is a complete, verified shard of frames ``start..stop-1``
    of this configuration, else why it must be (re)generated.

    Raises ValueError when a valid shard belongs to a different configuration (unless
    ``overwrite``).
    """
    if not path.exists():
        return "missing"
    try:
        reader = ShardReader(path)
    except CorruptShardError as exc:
        return f"damaged: {exc}"
    if reader.attrs["config"] != config_json:
        if overwrite:
            return "other configuration"
        theirs, ours = json.loads(reader.attrs["config"]), json.loads(config_json)
        diff = sorted(k for k in set(theirs) | set(ours) if theirs.get(k) != ours.get(k))
        raise ValueError(
            f"out_dir: shard {path} was generated with other settings (differing: {', '.join(diff)}); "
            "use another output directory or overwrite"
        )
    if reader.frame_start != start or len(reader) != stop - start:
        return f"covers frames {reader.frame_start}..{reader.frame_start + len(reader) - 1}"
    try:
        idx = reader.arrays(["frame_index"])["frame_index"]
        reader.arrays()  # reads every dataset: checksums
    except CorruptShardError as exc:
        return f"damaged: {exc}"
    if not np.array_equal(idx, np.arange(start, stop)):
        return "frame indices differ"
    return None


class _FrameWorker:
    """A worker of :func:`generate_dataset`: the frames of a task (a list of frame indices)."""

    def __init__(self, config: GenerationConfig):
        self.generator = FrameGenerator(config)

    def __call__(self, indices: list) -> list:
        return [self.generator.frame(i) for i in indices]


_frame_worker = _FrameWorker  # the worker factory handed to the executor (looked up at each run)


def generate_dataset(
    config: GenerationConfig,
    frames: int,
    out_dir,
    *,
    workers: int = 1,
    executor=None,
    progress: bool = True,
    overwrite: bool = False,
    on_shard=None,
) -> GenerationReport:
    """Generate ``frames`` frames into shards under ``out_dir`` (resumable).

    Parameters
    ----------
    config : GenerationConfig
    frames : int
        Total number of frames, positive.
    out_dir : str or Path
        Created when missing.
    workers : int
        Worker processes of this machine (``1`` = in this process); with ``executor``, leave it at 1.
    executor : LocalExecutor or RayExecutor, optional
        Where the frames are rendered (:mod:`ancsh.executors`; default ``LocalExecutor(workers)``).
        The shards do not depend on it. A worker that dies loses only unfinished shards: complete
        ones are on disk, and running again resumes (:class:`~ancsh.executors.WorkerLost` is raised
        when the executor does not retry the task itself).
    progress : bool
        Show a tqdm progress bar (on stderr).
    overwrite : bool
        Replace shards of another configuration and remove shards beyond ``frames``;
        otherwise either is a ValueError.
    on_shard : callable, optional
        Called as ``on_shard(shard_index, path)`` after each shard is written.

    Returns
    -------
    GenerationReport
    """
    from tqdm import tqdm

    if not isinstance(config, GenerationConfig):
        raise ValueError(f"config: expected GenerationConfig, got {type(config).__name__}")
    if isinstance(frames, bool) or not isinstance(frames, (int, np.integer)) or frames <= 0:
        raise ValueError(f"frames: expected a positive int, got {frames!r}")
    if isinstance(workers, bool) or not isinstance(workers, (int, np.integer)) or workers < 1:
        raise ValueError(f"workers: expected an int >= 1, got {workers!r}")
    from ..executors import LocalExecutor, RayExecutor

    if executor is None:
        executor = LocalExecutor(int(workers))
    elif not isinstance(executor, (LocalExecutor, RayExecutor)):
        raise ValueError(f"executor: expected a LocalExecutor or RayExecutor, got {type(executor).__name__}")
    elif workers != 1:
        raise ValueError(f"workers: give the worker count to the executor ({executor.describe()}), not both")
    t0 = time.perf_counter()
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    for stale in out.glob("*.h5.tmp*"):  # leftovers of a killed writer
        stale.unlink()
    cfg_json = config.to_json()
    ranges = _shard_ranges(int(frames), config.shard_size)
    paths = [out / shard_name(config, s) for s in range(len(ranges))]

    prefix = shard_name(config, 0)[: -len("00000.h5")]
    extra = sorted(p for p in out.glob(f"{prefix}*.h5") if p not in set(paths))
    if extra:
        if not overwrite:
            raise ValueError(
                f"out_dir: {out} holds shards beyond the requested {frames} frames ({extra[0].name} ...); "
                "use another output directory or overwrite"
            )
        for p in extra:
            p.unlink()

    todo, skipped, replaced = [], [], []
    for s, ((start, stop), path) in enumerate(zip(ranges, paths)):
        reason = _check_existing(path, cfg_json, start, stop, overwrite)
        if reason is None:
            skipped.append(s)
            continue
        if reason != "missing":
            replaced.append((s, reason))
        todo.append(s)

    chunk = max(1, min(16, config.shard_size))
    tasks = []
    for s in todo:
        start, stop = ranges[s]
        tasks.extend(list(range(i, min(i + chunk, stop))) for i in range(start, stop, chunk))
    remaining = sum(ranges[s][1] - ranges[s][0] for s in todo)
    split = config.split if config.urdf is None else "-"
    source = "procedural" if config.urdf is None else f"urdf:{config.urdf}"

    bar = tqdm(total=int(frames), initial=int(frames) - remaining, unit="frame", disable=not progress,
               desc=f"{config.name} {split}", dynamic_ncols=True)
    pending: dict[int, list] = {s: [] for s in todo}
    shard_of = {}
    for s in todo:
        for i in range(*ranges[s]):
            shard_of[i] = s
    generated = 0
    try:
        for batch in executor.imap(_frame_worker, (config,), tasks):
            for fr in batch:
                s = shard_of[fr.frame_index]
                pending[s].append(fr)
                generated += 1
                bar.update(1)
                start, stop = ranges[s]
                if len(pending[s]) == stop - start:
                    frames_s = sorted(pending.pop(s), key=lambda f: f.frame_index)
                    write_shard(paths[s], frames_s, split=split, source=source, config=cfg_json, frame_start=start)
                    if on_shard is not None:
                        on_shard(s, paths[s])
    finally:
        bar.close()
    return GenerationReport(
        out_dir=out,
        paths=tuple(paths),
        written=tuple(todo),
        skipped=tuple(skipped),
        replaced=tuple(replaced),
        frames_generated=generated,
        seconds=time.perf_counter() - t0,
    )
