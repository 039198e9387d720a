"""From a category spec and a folder of URDFs to a trained, calibrated, evaluated category folder.

``ancsh category build SPEC --urdfs DIR --out DIR`` runs :func:`build_category`, which runs the other commands
(``train``, ``calibrate``, ``evaluate``) in this process: it lives with them, on the floor of the commands.
The folder it writes is the category: ``--category DIR`` (or the search path ``ANCSH_CATEGORIES``) makes every
command use it.

Steps (each one resumes: run the same command again after an interruption and the finished steps are kept):

1. **check** -- the spec is read (:mod:`ancsh.data.category_spec`; a wrong spec stops here, naming the file and
   the key) and copied to ``category.toml``; every URDF is imported into it (:mod:`ancsh.data.importer`:
   ``catalog.json``, ``import_report.md``; the train / test split is by instance). Too few accepted objects, or
   none in a split, stops here, before any rendering or training, with the rejection reasons and the spec's keys
   they point at.
2. **render** -- training and test frames of the imported objects (``data/train``, ``data/test``), articulation,
   scale, camera (the spec's ``[viewpoint]``) and sensor noise randomised (:mod:`ancsh.data.generate`).
3. **train** -- the ANCSH network (``run/``, resumable; ``--time-limit-min`` is the CPU budget), exported as
   ``<name>.pt`` beside its training log and test scores.
4. **template** -- the template library of the train objects (``template.json``), used by render-and-compare.
5. **calibrate** -- ``p_good`` (``<name>_confidence.json``) and ``p_object`` (``<name>_object.json``, negatives from
   the built-in categories and clutter); a calibration the frames cannot support is reported, not installed.
6. **evaluate** -- the paper's metrics on the test objects (``evaluation/<name>.md``), and ``report.md``.
"""

from __future__ import annotations

import json
import re
import time
from dataclasses import asdict, dataclass
from pathlib import Path

from ..geometry._checks import check_int, check_number
from ..outputs import file_sha256

__all__ = ["BuildSettings", "MIN_OBJECTS", "SIZES", "build_category", "check_category"]

#: Accepted objects a build needs in each split (the report warns below :data:`FEW_OBJECTS`).
MIN_OBJECTS = {"train": 1, "test": 1}
#: Fewer imported objects than this: the report says that the network has seen too few instances to generalise.
FEW_OBJECTS = 8
STEPS = ("check", "render", "train", "template", "calibrate", "evaluate")
#: The files of the folder each step after training is made from (``{name}``: the category): a step done with the
#: same files and settings is kept, and done again when one of them changed (a template follows the catalog, a
#: calibration or an evaluation the network and the catalog's test objects).
_MADE_FROM = {"template": ("catalog.json",), "calibrate": ("{name}.pt", "catalog.json"),
              "evaluate": ("{name}.pt", "catalog.json")}


@dataclass(frozen=True)
class BuildSettings:
    """How much a build renders, trains and measures.

    Attributes
    ----------
    train_frames, test_frames : int
        Rendered frames of the train and test objects.
    time_limit_min : float
        Training budget (minutes of wall time on this machine's cores).
    max_steps : int or None
        Training steps at most (``None``: the training configuration's).
    calibrate_frames : int
        Frames of the ``p_good`` calibration (0: no calibration); ``p_object`` takes half as many.
    evaluate_frames : int
        Test frames of the evaluation.
    workers : int
        Processes rendering frames.
    seed : int
    init : str
        ``"auto"``: training starts from the shipped network nearest in structure (:func:`parent_network`: its
        configuration, and every parameter when the parts and joint types are the same, else the backbone);
        ``"none"``: from a random start with the default configuration.
    """

    train_frames: int = 4000
    test_frames: int = 400
    time_limit_min: float = 120.0
    max_steps: int | None = None
    calibrate_frames: int = 300
    evaluate_frames: int = 300
    workers: int = 2
    seed: int = 0
    init: str = "auto"

    def __post_init__(self):
        if self.init not in ("auto", "none"):
            raise ValueError(f"init: expected 'auto' (start from the nearest built-in network) or 'none', "
                             f"got {self.init!r}")
        for name in ("train_frames", "test_frames", "evaluate_frames", "workers"):
            object.__setattr__(self, name, check_int(getattr(self, name), name, minimum=1))
        object.__setattr__(self, "calibrate_frames", check_int(self.calibrate_frames, "calibrate_frames", minimum=0))
        object.__setattr__(self, "seed", check_int(self.seed, "seed", minimum=0))
        if self.max_steps is not None:
            object.__setattr__(self, "max_steps", check_int(self.max_steps, "max_steps", minimum=1))
        value = check_number(self.time_limit_min, "time_limit_min")
        if not value > 0:
            raise ValueError(f"time_limit_min: expected a positive number of minutes, got {self.time_limit_min!r}")
        object.__setattr__(self, "time_limit_min", value)


#: Named sizes: ``full`` (a few core-hours) and ``notebook`` (minutes: the pipeline end to end, not a good network).
SIZES = {
    "full": BuildSettings(),
    "notebook": BuildSettings(train_frames=256, test_frames=64, time_limit_min=3.0, max_steps=60, calibrate_frames=0,
                              evaluate_frames=16),
}


def _say(message: str) -> None:
    print(f"[category build] {message}", flush=True)


def check_category(spec, urdfs, out=None, *, overrides: dict | None = None) -> dict:
    """Step 1: read the spec and import the URDFs into it; stop with a clear error when they cannot make a category.

    Parameters
    ----------
    spec : str or Path
        The category spec file.
    urdfs : sequence of str or Path
        URDF files, object folders or folders of them.
    out : Path, optional
        The category folder: ``category.toml``, ``catalog.json``, ``import_report.md`` are written there.
    overrides : dict, optional
        Per-object import overrides (:func:`ancsh.data.importer.load_overrides`).

    Returns
    -------
    dict
        ``{"name", "catalog" (Catalog), "imported", "rejected", "train", "test"}``.

    Raises
    ------
    ancsh.data.category_spec.SpecError
        A wrong spec, or URDFs the spec cannot hold (naming the file and the keys the rejections point at).
    """
    from ..data import category_spec
    from ..data.conventions import register_category

    conv = category_spec.load_spec(spec)
    if out is not None:
        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
        target = out / category_spec.SPEC_FILE
        text = Path(conv.spec_path).read_text()
        if target.is_file() and target.read_text() != text and Path(conv.spec_path).resolve() != target.resolve():
            raise category_spec.SpecError(f"{target}: --out holds the build of another spec (its category.toml "
                                          f"differs from {conv.spec_path}); choose another --out or remove it")
        created = not target.is_file()
        if created:
            target.write_text(text)
        conv = register_category(out)
    else:
        created, conv = False, register_category(spec)
    try:
        return _import(spec, urdfs, out, conv, overrides)
    except category_spec.SpecError:
        if created:  # a spec that cannot make the category leaves no folder claiming it
            (out / category_spec.SPEC_FILE).unlink()
        raise


def _import(spec, urdfs, out, conv, overrides) -> dict:
    from ..data import category_spec
    from ..data.catalog import build_catalog, write_catalog

    catalog = build_catalog(list(urdfs), conv.name, overrides=overrides,
                            command=f"ancsh category build {spec} --urdfs {' '.join(map(str, urdfs))}")
    counts = {split: len(catalog.instances(conv.name, split)) for split in ("train", "test")}
    if out is not None:
        from ..studies.catalog_reports import write_import_report

        write_catalog(catalog, out / "catalog.json")
        write_import_report(catalog, out / "import_report.md")
    short = [f"{need} {split} object(s) needed, {counts[split]} imported" for split, need in MIN_OBJECTS.items()
             if counts[split] < need]
    if short:
        raise category_spec.SpecError(f"{spec}: {'; '.join(short)} ({len(catalog.objects)} accepted, "
                                      f"{len(catalog.rejected)} rejected){_rejections(catalog, conv)}")
    return {"name": conv.name, "catalog": catalog, "imported": len(catalog.objects), "rejected": len(catalog.rejected),
            **counts}


def _rejections(catalog, conv) -> str:
    """The rejection reasons, with the spec keys that decide them (a part no URDF has, a joint type none moves)."""
    if not catalog.rejected:
        return ""
    lines = []
    if not catalog.objects and all("moving part(s) of the kind" in r.reason for r in catalog.rejected):
        keys = []
        for k, j in enumerate(conv.joints):
            part = conv.part_names.index(j.child)
            names = "/".join(j.semantics or j.links) or "any movable link"
            keys.append(f"parts[{part}].{'semantics' if j.semantics else 'links'} ({names}) with joints[{k}].type "
                        f"{j.type.value!r}")
        lines.append("no URDF has the moving parts the spec names: " + "; ".join(keys))
    reasons = {}
    for r in catalog.rejected:
        reasons.setdefault(r.reason, []).append(r.name)
    for reason, names in list(reasons.items())[:5]:
        lines.append(f"{', '.join(names[:4])}{' ...' if len(names) > 4 else ''}: {reason}")
    return "\n  " + "\n  ".join(lines)


def _render(name: str, out: Path, settings: BuildSettings, progress: bool) -> dict:
    """Step 2: the train and test frames (complete shards are kept)."""
    from ..data.generate import GenerationConfig, generate_dataset
    from ..executors import make_executor

    executor = make_executor("local", settings.workers)
    made = {}
    for split, frames in (("train", settings.train_frames), ("test", settings.test_frames)):
        config = GenerationConfig(category=name, split=split, seed=settings.seed + (split == "test"),
                                  real=str(out / "catalog.json"))
        report = generate_dataset(config, frames, out / "data" / split, executor=executor,
                                  progress=progress, overwrite=True)
        made[split] = {"frames": frames, "generated": report.frames_generated, "seconds": round(report.seconds, 1)}
        _say(f"render {split}: {frames} frames ({report.frames_generated} new, {report.seconds:.0f} s)")
    return made


def _quiet(progress: bool) -> list:
    """``["--no-progress"]`` unless the build shows progress."""
    return [] if progress else ["--no-progress"]


def _cli(words: list) -> None:
    """Run one ``ancsh`` command in this process; a non-zero exit is an error naming it."""
    from . import main

    code = main([str(w) for w in words])
    if code:
        raise RuntimeError(f"`ancsh {' '.join(map(str, words))}` exited with {code}")


def parent_network(name: str) -> tuple[str, str] | None:
    """The shipped network a new category's training starts from, and how (``TrainConfig.init_match``).

    Among the built-in categories with shipped weights: first those with the same joint types in the same order
    (every parameter copied, ``"all"``), then those whose joints are all of the new category's kinds, then any
    (``"matching"``: the backbone copied, the part-sized heads start afresh); among equals the nearest typical size.
    ``None`` when no network is shipped.
    """
    import math

    from ..data.conventions import CONVENTIONS
    from ..learned.network.weights import shipped_categories

    conv = CONVENTIONS[name]
    types = tuple(j.type for j in conv.joints)
    ranked = []
    for other in shipped_categories():
        c = CONVENTIONS[other]
        theirs = tuple(j.type for j in c.joints)
        rank = 0 if theirs == types else 1 if set(theirs) == set(types) else 2
        ranked.append((rank, abs(math.log(c.typical_size / conv.typical_size)), other))
    if not ranked:
        return None
    rank, _, best = min(ranked)
    return best, "all" if rank == 0 else "matching"


def _train_config(name: str, out: Path, settings: BuildSettings) -> tuple[Path, dict]:
    """The training configuration (``train_config.json``): the parent network's, started from it (or the default)."""
    from ..learned.network.config import TrainConfig
    from ..learned.network.weights import weights_path

    fields = {"category": name, "seed": settings.seed, "max_steps": settings.max_steps or 6000, "pose_val_every": 0}
    parent = parent_network(name) if settings.init == "auto" else None
    record = {"parent": None}
    if parent is not None:
        other, match = parent
        saved = json.loads(weights_path(other).with_name(f"{other}_config.json").read_text())
        known = set(TrainConfig.__dataclass_fields__)
        base = {k: v for k, v in saved.items() if k in known and v is not None}
        fields = {**base, **fields, "init_weights": str(weights_path(other)), "init_match": match}
        record = {"parent": other, "init_match": match}
    path = out / "train_config.json"
    path.write_text(json.dumps(TrainConfig.from_dict(fields).to_dict(), indent=1) + "\n")
    return path, record


def _train(name: str, out: Path, settings: BuildSettings, progress: bool) -> dict:
    run = out / "run"
    weights = out / f"{name}.pt"
    config, record = _train_config(name, out, settings)
    words = ["train", "--category", out, "--config", config, "--data", out / "data" / "train", "--test-data",
             out / "data" / "test", "--out", run, "--time-limit-min", settings.time_limit_min, *_quiet(progress),
             "--export", weights]
    if (run / "last.pt").is_file():
        words.append("--resume")
    _cli(words)
    metrics = out / f"{name}_test_metrics.json"
    last = _history_last(run)  # the run's totals over all its resumptions, not this call's
    return {"seconds": round(float(last.get("elapsed_s") or 0.0), 1), "steps": int(float(last.get("step") or 0)),
            **record,
            "test_metrics": json.loads(metrics.read_text()) if metrics.is_file() else None}


def _history_last(run: Path) -> dict:
    """The last row of a run's ``history.csv`` (``{}`` without one)."""
    import csv

    path = run / "history.csv"
    if not path.is_file():
        return {}
    with path.open() as f:
        rows = list(csv.DictReader(f))
    return rows[-1] if rows else {}


def _template(name: str, out: Path) -> dict:
    from ..data.templates import build_template_library, write_template_library

    library = build_template_library(name, real=str(out / "catalog.json"))
    write_template_library(library, out / "template.json")
    return {"entries": len(library)}


def _calibrate(out: Path, settings: BuildSettings, progress: bool) -> dict:
    done = {}
    if settings.calibrate_frames == 0:
        return {"p_good": "not calibrated (calibrate_frames 0)", "p_object": "not calibrated (calibrate_frames 0)"}
    for key, extra, frames in (("p_good", [], settings.calibrate_frames),
                               ("p_object", ["--object"], max(8, settings.calibrate_frames // 2))):
        words = ["calibrate", "--category", out, *extra, "--frames", frames, "--seed", settings.seed + 7,
                 "--out", out / "calibration", "--install", *_quiet(progress)]
        try:
            _cli(words)
            done[key] = "installed"
        except RuntimeError as exc:  # too few good or bad fits: reported, predict runs without it
            done[key] = f"not installed: {exc}"
            done["complete"] = False  # tried again when the build runs again
            _say(f"calibrate {key}: {done[key]}")
    return done


def _evaluate(out: Path, settings: BuildSettings, progress: bool) -> dict:
    _cli(["evaluate", "--category", out, "--frames", settings.evaluate_frames, "--seed", settings.seed,
          "--out", out / "evaluation", *_quiet(progress)])
    return {"frames": settings.evaluate_frames}


def build_category(spec, urdfs, out, *, settings: BuildSettings = SIZES["full"], overrides: dict | None = None,
                   steps=STEPS, progress: bool = False) -> Path:
    """Build a category folder from a spec and URDFs (module docstring); returns ``out / "report.md"``.

    Parameters
    ----------
    spec : str or Path
    urdfs : sequence of str or Path
    out : str or Path
        The category folder (created; a run interrupted in it resumes).
    settings : BuildSettings
    overrides : dict, optional
        Per-object import overrides.
    steps : sequence of str
        The steps to run (default all, in order; :data:`STEPS`).
    progress : bool
        Progress bars of the rendering, training, calibration and evaluation.
    """
    if not isinstance(settings, BuildSettings):
        raise ValueError(f"settings: expected BuildSettings, got {type(settings).__name__}")
    unknown = [s for s in steps if s not in STEPS]
    if unknown:
        raise ValueError(f"steps: unknown step(s) {unknown}; known: {', '.join(STEPS)}")
    out = Path(out)
    start = time.perf_counter()
    state_path = out / "build.json"
    checked = check_category(spec, urdfs, out, overrides=overrides)
    name = checked["name"]
    state = json.loads(state_path.read_text()) if state_path.is_file() else {}
    state.update(name=name, settings=asdict(settings), spec=str(spec), urdfs=[str(u) for u in urdfs],
                 check={k: checked[k] for k in ("imported", "rejected", "train", "test")})
    _say(f"check: {name}: {checked['imported']} objects imported ({checked['train']} train, {checked['test']} test), "
         f"{checked['rejected']} rejected")
    progress = bool(progress)
    work = {"render": lambda: _render(name, out, settings, progress),
            "train": lambda: _train(name, out, settings, progress),
            "template": lambda: _template(name, out),
            "calibrate": lambda: _calibrate(out, settings, progress),
            "evaluate": lambda: _evaluate(out, settings, progress)}
    for step in STEPS[1:]:
        if step not in steps:
            continue
        files = [out / f.format(name=name) for f in _MADE_FROM.get(step, ())]
        made_from = [file_sha256(f) for f in files] if files and all(f.is_file() for f in files) else None
        done = state.get(step)
        if made_from is not None and isinstance(done, dict) and done.get("made_from_sha256") == made_from \
                and done.get("settings") == asdict(settings) and done.get("complete", True):
            _say(f"{step}: kept (done from the same {', '.join(f.name for f in files)} and settings)")
            continue
        _say(f"{step} ...")
        state[step] = {**work[step](), "settings": asdict(settings)}
        if made_from is not None:
            state[step]["made_from_sha256"] = made_from
        state_path.write_text(json.dumps(state, indent=1, default=str) + "\n")
    state["seconds"] = round(time.perf_counter() - start, 1)
    state_path.write_text(json.dumps(state, indent=1, default=str) + "\n")
    report = out / "report.md"
    report.write_text(_report(out, state))
    _say(f"wrote {report}")
    return report


#: The network's test scores shown in the report: (key, what it is).
_SCORES = (("test_frames", "test frames"), ("seg_acc", "segmentation accuracy"), ("npcs_err", "NPCS error"),
           ("axis_err_deg", "joint axis error (deg)"), ("seg_acc_majority", "segmentation: the majority part"),
           ("npcs_err_zero", "NPCS: all zero"))


def _metrics_table(name: str, metrics: dict, parent: str | None) -> list:
    """The network's scores on the held-out test frames beside the parent network's on its own category's."""
    from ..learned.network.weights import weights_path

    theirs = {}
    if parent is not None:
        path = weights_path(parent).with_name(f"{parent}_test_metrics.json")
        theirs = json.loads(path.read_text()) if path.is_file() else {}
    rows = [(label, metrics.get(key), theirs.get(key)) for key, label in _SCORES if key in metrics]
    if not rows:
        return []

    def cell(v):
        return "-" if v is None else f"{v:.4g}" if isinstance(v, float) else str(v)

    head = f"| score | `{name}` (its test objects) |" + (f" shipped `{parent}` (its test frames) |" if theirs else "")
    out = ["Scores of the network on the test frames (the last two rows: trivial baselines)"
           + (", beside the network it started from on its own category's" if theirs else "") + ":", "", head,
           "|---|---|" + ("---|" if theirs else "")]
    out += [f"| {label} | {cell(ours)} |" + (f" {cell(other)} |" if theirs else "") for label, ours, other in rows]
    return out + [""]


def _report(out: Path, state: dict) -> str:
    name = state["name"]
    s = state["settings"]
    lines = [f"# Category `{name}`: build report", "",
             f"Built by `ancsh category build {state['spec']} --urdfs {' '.join(state['urdfs'])} --out {out}` "
             f"(settings: {s['train_frames']} training frames, {s['test_frames']} test frames, training budget "
             f"{s['time_limit_min']:g} min, max steps {s['max_steps']}, {s['calibrate_frames']} calibration frames, "
             f"{s['evaluate_frames']} evaluation frames, seed {s['seed']}); the last run of the command took "
             f"{state.get('seconds', 0):.0f} s (a run keeps the steps done before it: the training's own time is "
             "below).", "",
             "Use it: `--category " + str(out) + "` with `predict`, `track`, `evaluate`, `calibrate`, or put the "
             "folder's parent on `ANCSH_CATEGORIES`.", "",
             "## Objects", "",
             f"{state['check']['imported']} imported ({state['check']['train']} train, {state['check']['test']} test), "
             f"{state['check']['rejected']} rejected: `import_report.md`."
             + (f" **Only {state['check']['imported']} objects: a network trained on so few instances is not expected "
                f"to carry to other objects of the category (give at least {FEW_OBJECTS}).**"
                if state['check']['imported'] < FEW_OBJECTS else ""), ""]
    if "train" in state:
        t = state["train"]
        copied = "every parameter" if t.get("init_match") == "all" else "its backbone"
        start = (f"started from the shipped `{t['parent']}` network ({copied}, its configuration)" if t.get("parent")
                 else "started from a random initialisation")
        lines += ["## Training", "", f"{t.get('steps', '?')} steps in {t['seconds']:.0f} s, {start}; the network "
                  f"`{name}.pt`, its curves "
                  f"`{name}_curves.png`, its configuration `train_config.json`.", ""]
        lines += _metrics_table(name, t.get("test_metrics") or {}, t.get("parent"))
    if "calibrate" in state:
        lines += ["## Calibration", ""] + [f"- `{k}`: {v}" for k, v in state["calibrate"].items()
                                            if k in ("p_good", "p_object")] + [""]
    evaluation = out / "evaluation" / f"{name}.md"
    if evaluation.is_file():
        body = evaluation.read_text().partition("\n")[2]  # without its title
        body = re.sub(r"\]\(([^/():]+\.png)\)", r"](evaluation/\1)", body)  # its pictures, from the folder's top
        lines += ["## Evaluation on the test objects (`evaluation/`)", "", body.replace("\n# ", "\n### ")
                  .replace("\n## ", "\n### ")]
    return "\n".join(lines).rstrip() + "\n"
