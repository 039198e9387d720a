"""Where the shipped ANCSH networks stand against the paper's Table 1 (the learned-accuracy targets).

The figures are read back from the evaluation reports that ``ancsh evaluate`` wrote
(``<category>.json``; with ``--real`` it also holds the real test split's summary), never
re-measured here: per part, the ANCSH-exact (``exact_reduced``) mean rotation error on the
procedural test split against the paper's ANCSH row, the joint-axis error against the paper's, and
the real split's rotation error as a ratio of the procedural one (goal: at most
:data:`REAL_RATIO_GOAL`). A report whose weights differ from the shipped file (SHA-256) is marked
stale: its figures describe other weights (or frames of an older generator).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

__all__ = [
    "NETWORK_METHOD", "REAL_RATIO_GOAL", "REFINED_METHOD", "TARGET_METHOD", "TRAINING_BUDGET_MIN", "BudgetProjection",
    "TargetRow", "budget_projection", "refiner_minutes", "refiner_roots",
    "collect_targets", "limit_lines", "roll_gains", "target_lines",
]

TARGET_METHOD = "exact_reduced"
"""The method the targets are stated for (ANCSH-exact, reduced coordinates)."""

REFINED_METHOD = "template"
"""The report's row of the same fits refined against the category template (``ancsh evaluate --refine template``),
shown beside the targets' method."""

NETWORK_METHOD = "network"
"""The report's row of the same fits refined by the refinement network (``ancsh evaluate --refine network``), shown
beside the targets' method."""

REAL_RATIO_GOAL = 1.25
"""Goal for the real split: rotation error at most this multiple of the procedural split's, per part."""

TRAINING_BUDGET_MIN = 960.0
"""Training budget per category: 16 CPU-core-hours (one torch thread = one core), in minutes -- issue 32's, which lifted
the earlier cap of 4; it covers every CPU training of the category (first stage, refinement network, runs not
shipped)."""

UNSHIPPED_PATH = Path(__file__).resolve().parents[1] / "weights" / "unshipped_training.json"
"""Ledger of training runs whose networks were not shipped (they spent budget all the same)."""


def refiner_minutes(rows: list[dict], roots: dict[str, float] | None = None) -> dict[str, float]:
    """Per category, the training minutes of the shipped refinement network's lineage beyond the first stage's:
    its own and those of the networks it was fine-tuned from (an earlier refiner), less the first stage's lineage.

    Parameters
    ----------
    rows : list of dict
        :func:`ancsh.learned.network.weights.weights_summary` rows (``kind``, ``refiner``, ``category``,
        ``train_min``, ``parent_min``).
    roots : dict, optional
        ``{category: minutes}`` of the first-stage lineage that the refiner's lineage holds, where it is not the
        shipped first stage's whole lineage: a first stage fine-tuned again after its refiner was trained
        (:func:`refiner_roots`). Without an entry the refiner is taken to descend from the shipped first stage.
    """
    roots = roots or {}
    first = {r["category"]: r["train_min"] + r["parent_min"] for r in rows if r["kind"] == "ancsh" and not r.get("refiner")}
    return {r["category"]: max(0.0, r["train_min"] + r["parent_min"] - roots.get(r["category"], first[r["category"]]))
            for r in rows if r["kind"] == "ancsh" and r.get("refiner") and r["category"] in first}


def refiner_roots(path=None) -> dict[str, float]:
    """The ledger's ``refiner_first_stage_min`` (:data:`UNSHIPPED_PATH`): per category whose first stage was fine-tuned
    again after its refinement network was trained, the minutes of the (earlier) first-stage lineage that the
    refiner's lineage holds; ``{}`` without the file or the entry (see :func:`refiner_minutes`). The entry holds while the
    shipped refiner descends from that earlier first stage (a refiner fine-tuned again from it still does); drop it
    when a refiner initialised from the current first stage is shipped. A first stage replaced by one of another
    lineage shares nothing with the refiner's: its entry is 0 (the refiner's whole lineage counts).

    Raises
    ------
    ValueError
        For an entry that is not a number of minutes >= 0 (naming the file and the category).
    """
    path, ledger = _ledger(path)
    roots = (ledger or {}).get("refiner_first_stage_min", {})
    if not isinstance(roots, dict):
        raise ValueError(f"{path}: refiner_first_stage_min: expected {{category: minutes}}")
    return {str(c): _ledger_minutes(path, f"refiner_first_stage_min.{c}", m) for c, m in roots.items()}


def _ledger(path) -> tuple[Path, dict | None]:
    """The ledger's path (:data:`UNSHIPPED_PATH` for ``None``) and its content (``None`` without the file)."""
    path = UNSHIPPED_PATH if path is None else Path(path)
    return path, (json.loads(path.read_text()) if path.is_file() else None)


def _ledger_minutes(path: Path, where: str, value) -> float:
    """``value`` as minutes >= 0, else a ``ValueError`` naming the ledger ``path`` and the entry ``where``."""
    try:
        minutes = float(value)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{path}: {where}: expected minutes ({exc})") from exc
    if not minutes >= 0:
        raise ValueError(f"{path}: {where}: expected >= 0, got {minutes}")
    return minutes


def unshipped_minutes(path=None) -> dict[str, float]:
    """Training minutes per category of runs that were not shipped (:data:`UNSHIPPED_PATH`: ``{"runs":
    [{"category", "minutes", "what"}, ...]}``); ``{}`` without the file.

    Raises
    ------
    ValueError
        For a ledger that is not such a list (naming the file and the entry).
    """
    path, ledger = _ledger(path)
    if ledger is None:
        return {}
    runs = ledger.get("runs")
    if not isinstance(runs, list):
        raise ValueError(f"{path}: expected {{\"runs\": [...]}}")
    out: dict[str, float] = {}
    for i, r in enumerate(runs):
        if not isinstance(r, dict) or "category" not in r or "minutes" not in r:
            raise ValueError(f"{path}: runs[{i}]: expected a category and minutes")
        category = str(r["category"])
        out[category] = out.get(category, 0.0) + _ledger_minutes(path, f"runs[{i}].minutes", r["minutes"])
    return out


@dataclass(frozen=True)
class TargetRow:
    """One category's standing, read from its evaluation report.

    Attributes
    ----------
    category : str
    part_names, joint_names : tuple of str
    frames : int
        Procedural test frames of the report.
    rot_deg : tuple of float
        Mean rotation error per part (degrees), ANCSH-exact, procedural test split.
    axis_deg : tuple of float
        Mean joint-axis angle error per joint (degrees, camera frame).
    paper_rot_deg, paper_axis_deg : tuple of float or None
        The paper's Table 1 ANCSH row (``None``: the paper has no such category or column).
    real_frames : int
        Real-split frames in the report (0: none evaluated).
    real_rot_deg : tuple of float or None
        Mean rotation error per part on the real split.
    report_sha256 : str
        SHA-256 of the weights the report evaluated.
    shipped_sha256 : str or None
        SHA-256 of the shipped weights file (``None``: none shipped).
    generator_version : int or None
        Version of the category's frame generator the report rendered with (:func:`ancsh.data.procedural.generator_version`) (``None``: not recorded by
        reports written before it was).
    refined_rot_deg : tuple of float or None
        Mean rotation error per part of the same fits refined against the category template
        (:data:`REFINED_METHOD`, ``ancsh evaluate --refine template``); ``None`` when the report has no such row.
    network_rot_deg, network_axis_deg : tuple of float or None
        Mean rotation error per part and joint-axis error per joint of the same fits refined by the refinement
        network (:data:`NETWORK_METHOD`, ``ancsh evaluate --refine network``); ``None`` without such a row.
    """

    category: str
    part_names: tuple[str, ...]
    joint_names: tuple[str, ...]
    frames: int
    rot_deg: tuple[float, ...]
    axis_deg: tuple[float, ...]
    paper_rot_deg: tuple[float, ...] | None
    paper_axis_deg: tuple[float, ...] | None
    real_frames: int
    real_rot_deg: tuple[float, ...] | None
    report_sha256: str
    shipped_sha256: str | None
    generator_version: int | None = None
    refined_rot_deg: tuple[float, ...] | None = None
    network_rot_deg: tuple[float, ...] | None = None
    network_axis_deg: tuple[float, ...] | None = None

    @property
    def stale(self) -> str:
        """Why the report does not describe the shipped weights on today's frames ('' when it does)."""
        from ..data.procedural import generator_version

        if self.shipped_sha256 is None or self.report_sha256 != self.shipped_sha256:
            return "other weights"
        today = generator_version(self.category)
        if self.generator_version is None:
            return f"frame generator version not recorded (re-run ancsh evaluate; today's is {today})"
        if self.generator_version != today:
            return f"frames of generator version {self.generator_version}, not {today}"
        return ""

    @property
    def paper_ratio(self) -> tuple[float, ...] | None:
        """Ours / the paper's rotation error, per part."""
        return _over(self.rot_deg, self.paper_rot_deg)

    @property
    def rotation_met(self) -> bool | None:
        """Every part at most the paper's rotation error (``None`` without a paper row)."""
        return _all_at_most(self.paper_ratio, 1.0)

    @property
    def refined_ratio(self) -> tuple[float, ...] | None:
        """The template-refined rotation error over the paper's, per part (``None`` without either)."""
        return _over(self.refined_rot_deg, self.paper_rot_deg)

    @property
    def refined_met(self) -> bool | None:
        """Every part of the template-refined fits at most the paper's rotation error (``None`` without either)."""
        return _all_at_most(self.refined_ratio, 1.0)

    @property
    def network_ratio(self) -> tuple[float, ...] | None:
        """The network-refined rotation error over the paper's, per part (``None`` without either)."""
        return _over(self.network_rot_deg, self.paper_rot_deg)

    @property
    def network_met(self) -> bool | None:
        """Every part of the network-refined fits at most the paper's rotation error (``None`` without either)."""
        return _all_at_most(self.network_ratio, 1.0)

    @property
    def axis_met(self) -> bool | None:
        """Every joint axis at most the paper's error (``None`` without a paper figure)."""
        if self.paper_axis_deg is None:
            return None
        return all(o <= p for o, p in zip(self.axis_deg, self.paper_axis_deg))

    @property
    def real_ratio(self) -> tuple[float, ...] | None:
        """Real / procedural rotation error, per part (``None`` without a real split)."""
        return _over(self.real_rot_deg, self.rot_deg)

    @property
    def real_met(self) -> bool | None:
        """Every part's real / procedural ratio at most :data:`REAL_RATIO_GOAL`."""
        return _all_at_most(self.real_ratio, REAL_RATIO_GOAL)


def _over(values, reference) -> tuple[float, ...] | None:
    """``values / reference`` per entry (``None`` when either is missing)."""
    if values is None or reference is None:
        return None
    return tuple(v / r for v, r in zip(values, reference))


def _all_at_most(ratios, bound: float) -> bool | None:
    """Every ratio at most ``bound`` (``None`` when there are none)."""
    return None if ratios is None else all(x <= bound for x in ratios)


def _means(summary: dict, metric: str, where: Path, method: str = TARGET_METHOD) -> tuple[float, ...]:
    try:
        values = summary["methods"][method][metric]["mean"]
    except (KeyError, TypeError) as exc:
        raise ValueError(f"{where}: no {method} {metric} means in the report ({exc!r})") from None
    return tuple(float("nan") if v is None else float(v) for v in values)


def _read_row(path: Path, shipped_sha256: str | None) -> TargetRow:
    try:
        report = json.loads(path.read_text())
        category, settings, summary = report["category"], report["settings"], report["summary"]
    except (OSError, ValueError, KeyError) as exc:
        raise ValueError(f"{path}: not an `ancsh evaluate` report ({exc!r})") from None
    paper = ((report.get("paper") or {}).get("table1") or {}).get("ANCSH")
    real = report.get("real")
    return TargetRow(
        category=category,
        part_names=tuple(settings["part_names"]),
        joint_names=tuple(settings["joint_names"]),
        frames=int(settings["frames"]),
        rot_deg=_means(summary, "rot_deg", path),
        axis_deg=_means(summary, "axis_deg", path),
        paper_rot_deg=None if not paper else tuple(paper["rot_deg"]),
        paper_axis_deg=None if not paper or "axis_deg" not in paper else tuple(paper["axis_deg"]),
        real_frames=0 if real is None else int(real["settings"]["frames"]),
        real_rot_deg=None if real is None else _means(real["summary"], "rot_deg", path),
        report_sha256=str(settings["weights_sha256"]),
        shipped_sha256=shipped_sha256,
        generator_version=settings.get("generator_version"),
        refined_rot_deg=_means(summary, "rot_deg", path, REFINED_METHOD)
        if REFINED_METHOD in (summary.get("methods") or {}) else None,
        network_rot_deg=_means(summary, "rot_deg", path, NETWORK_METHOD)
        if NETWORK_METHOD in (summary.get("methods") or {}) else None,
        network_axis_deg=_means(summary, "axis_deg", path, NETWORK_METHOD)
        if NETWORK_METHOD in (summary.get("methods") or {}) else None,
    )


def collect_targets(reports_dir) -> tuple[list[TargetRow], list[str]]:
    """Read ``<category>.json`` in ``reports_dir`` for every category with shipped ANCSH weights.

    Returns the rows (category order) and the categories without a report. Raises ``ValueError``
    naming the argument when ``reports_dir`` is not a folder, and naming the file when a report
    cannot be read.
    """
    from ..outputs import file_sha256
    from ..learned.network.weights import shipped_categories, weights_path

    reports = Path(reports_dir)
    if not reports.is_dir():
        raise ValueError(f"reports_dir: {reports} is not a folder")
    rows, missing = [], []
    for category in shipped_categories("ancsh"):
        path = reports / f"{category}.json"
        if not path.is_file():
            missing.append(category)
            continue
        rows.append(_read_row(path, file_sha256(weights_path(category))))
    return rows, missing


def _join(values, spec: str) -> str:
    return " / ".join("-" if v != v else format(v, spec) for v in values)


def _verdict(met: bool | None) -> str:
    return "" if met is None else (" (met)" if met else " (**not met**)")


def _refined_cell(r: TargetRow) -> str:
    if r.refined_rot_deg is None:
        return "- (no `--refine template` row)"
    ratio = r.refined_ratio
    return _join(r.refined_rot_deg, ".2f") + ("" if ratio is None else ", " + _join(ratio, ".1f") + "x" + _verdict(r.refined_met))


def _network_cell(r: TargetRow) -> str:
    if r.network_rot_deg is None:
        return "- (no `--refine network` row)"
    ratio = r.network_ratio
    text = _join(r.network_rot_deg, ".2f") + ("" if ratio is None else ", " + _join(ratio, ".1f") + "x" + _verdict(r.network_met))
    return text + "; axis " + _join(r.network_axis_deg, ".2f") + (
        "" if r.paper_axis_deg is None else ", " + _join(_over(r.network_axis_deg, r.paper_axis_deg), ".1f") + "x")


def target_lines(rows: list[TargetRow], missing: list[str], training_min: dict[str, tuple]) -> list[str]:
    """Markdown: one row per category (figures of :func:`collect_targets`), with the training time spent
    on its shipped networks against :data:`TRAINING_BUDGET_MIN`: ``training_min[category]`` is
    ``(own, parent)`` or ``(own, parent, refiner)`` minutes: the first stage's own, those of the network it was
    fine-tuned from (0 if none), and the refinement network's own (0 if none)."""
    lines = [
        "| category | parts | frames (real) | rotation (°), ours | paper | ours / paper | joint axis (°), ours | paper "
        "| real / procedural rotation | + category template: rotation (°), / paper | + refinement network: rotation (°), "
        f"/ paper; joint axis (°), / paper | training (min) of {TRAINING_BUDGET_MIN:.0f}: first stage + its parent "
        "(+ refiner) | report |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        ratio = r.paper_ratio
        real = r.real_ratio
        own, parent, refiner = (tuple(training_min.get(r.category, (float("nan"), 0.0))) + (0.0,))[:3]
        minutes = "-" if own != own else (f"{own:.0f}" if not parent else f"{own:.0f} + {parent:.0f}")
        if own == own and refiner:
            minutes += f" (+ {refiner:.0f})"
        lines.append(
            f"| {r.category} | {', '.join(r.part_names)} | {r.frames} ({r.real_frames}) | {_join(r.rot_deg, '.2f')} | "
            f"{'-' if r.paper_rot_deg is None else _join(r.paper_rot_deg, '.1f')} | "
            f"{'-' if ratio is None else _join(ratio, '.1f') + 'x' + _verdict(r.rotation_met)} | "
            f"{_join(r.axis_deg, '.2f')} | "
            f"{'-' if r.paper_axis_deg is None else _join(r.paper_axis_deg, '.1f') + _verdict(r.axis_met)} | "
            f"{'-' if real is None else _join(real, '.2f') + 'x' + _verdict(r.real_met)} | "
            f"{_refined_cell(r)} | "
            f"{_network_cell(r)} | "
            f"{minutes} | "
            f"{'stale: ' + r.stale if r.stale else 'current'} |"
        )
    if missing:
        lines += ["", f"No report for: {', '.join(missing)} (`ancsh evaluate --category C --real builtin --out DIR`)."]
    return lines


@dataclass(frozen=True)
class BudgetProjection:
    """What more of the same training projects for one category, against what its targets need.

    Attributes
    ----------
    category : str
    needed : float
        The factor by which the worst part's rotation error must fall to meet the paper's
        (``min(paper / ours)`` over parts; ``nan`` without a paper row; >= 1 once met).
    spent_min, left_min : float
        Training minutes spent on the shipped network and its parent, and those left of
        :data:`TRAINING_BUDGET_MIN` (never negative).
    npcs_factor : float
        The validation NPCS error's power-law projection over the remaining budget: error at
        ``own + left`` minutes over error at ``own`` (``nan`` without a learning curve).
    pose_factor : float
        The same projection from a power law fitted to the pose validations (fitted rotation +
        joint-axis error, the quantity the targets judge; ``nan`` with fewer than 3).
    pose_exponent : float
        That power law's exponent (``nan`` without it; >= 0: the pose score no longer falls).
    roll_gain : float
        The shipped network's camera-roll gain (:mod:`ancsh.studies.equivariance`; ``nan`` when not
        measured).
    test_over_train : float
        Mean fitted rotation error on the held-out test instances over that on new views of the training
        instances, procedural split, averaged over parts (``ancsh bench train-test-gap``; ``nan`` when not
        measured on the shipped weights): near 1, the network is under-fitted.
    """

    category: str
    needed: float
    spent_min: float
    left_min: float
    npcs_factor: float
    pose_factor: float
    pose_exponent: float
    roll_gain: float = float("nan")
    test_over_train: float = float("nan")

    @property
    def reachable(self) -> bool | None:
        """Whether either projection over the remaining budget reaches the needed factor (``None`` when
        neither projection or no paper row exists)."""
        best = min((f for f in (self.npcs_factor, self.pose_factor) if f == f), default=float("nan"))
        if best != best or self.needed != self.needed:
            return None
        return best <= self.needed


def budget_projection(row: TargetRow, weights_row: dict, roll_gain: float = float("nan"),
                      unshipped_min: float = 0.0, test_over_train: float = float("nan"),
                      refiner_min: float = 0.0) -> BudgetProjection:
    """Project more of the same training over the rest of the budget, for one category.

    Parameters
    ----------
    row : TargetRow
        The category's standing (:func:`collect_targets`).
    weights_row : dict
        The shipped ANCSH network's row of :func:`ancsh.learned.network.weights.weights_summary` (``train_min``,
        ``parent_min``, ``curve``, ``pose_curve``).
    roll_gain : float
        Its measured camera-roll gain, passed through (``nan``: not measured).
    unshipped_min : float
        Minutes of the category's runs that were not shipped (:func:`unshipped_minutes`): spent budget.
    test_over_train : float
        Its measured train/test rotation ratio (:func:`train_test_ratios`), passed through.
    refiner_min : float
        Minutes of the shipped refinement network's own training (spent budget; its parent is the first stage).

    Notes
    -----
    Both projections assume the power law ``err = a * t**b`` fitted to the run's own history
    (:func:`ancsh.learned.network.weights.learning_curve_fit`) holds up to ``t = own + left`` minutes; curves
    usually flatten, so they are optimistic. The NPCS error is only a proxy for the pose; the pose
    validations measure it (64 frames, about ±1° of noise each).
    """
    from ..learned.network.weights import learning_curve_fit

    own = float(weights_row.get("train_min", float("nan")))
    parent = float(weights_row.get("parent_min") or 0.0)
    spent = own + parent + float(unshipped_min) + float(refiner_min)
    left = max(0.0, TRAINING_BUDGET_MIN - spent) if spent == spent else float("nan")
    ratio = row.paper_ratio
    needed = float("nan") if ratio is None or not all(math.isfinite(x) and x > 0 for x in ratio) else 1.0 / max(ratio)

    def project(exponent: float) -> float:
        if exponent != exponent or not own > 0 or left != left:
            return float("nan")
        return math.exp(exponent * math.log((own + left) / own))

    curve = weights_row.get("curve")
    npcs_factor = project(float(curve["exponent"])) if curve else float("nan")
    pose = [p for p in weights_row.get("pose_curve") or () if p["minutes"] > 0 and p["score"] > 0]
    pose_exponent = float("nan")
    if len(pose) >= 3:
        fit = learning_curve_fit([p["minutes"] for p in pose], [p["score"] for p in pose], tail_fraction=1.0)
        pose_exponent = fit["exponent"]
    pose_factor = float("nan") if pose_exponent != pose_exponent else (
        1.0 if pose_exponent >= 0 else project(pose_exponent))
    return BudgetProjection(row.category, needed, spent, left, npcs_factor, pose_factor, pose_exponent,
                            float(roll_gain), float(test_over_train))


def _report_entries(path, key: str, what: str):
    """``json[key]`` of a benchmark's JSON report; ``None`` when ``path`` does not exist."""
    path = Path(path)
    if not path.is_file():
        return None
    try:
        return json.loads(path.read_text())[key]
    except (OSError, ValueError, KeyError) as exc:
        raise ValueError(f"{path}: not a {what} report ({exc!r})") from None


def is_shipped(category, weights_sha256, kind: str = "ancsh") -> bool:
    """Whether ``weights_sha256`` is that of the weights of ``kind`` (``"ancsh"``, ``"refine"``, ...) shipped for
    ``category`` (False when none are)."""
    from ..outputs import file_sha256
    from ..learned.network.weights import weights_path

    if not category or not weights_sha256:
        return False
    shipped = weights_path(category, kind)
    return shipped.is_file() and file_sha256(shipped) == weights_sha256


def train_test_ratios(path) -> dict[str, float]:
    """Per category, the procedural split's test-instance over training-instance mean rotation error, averaged over
    parts, from a ``train_test_gap.json`` of ``ancsh bench train-test-gap`` (rows of the shipped weights only; {}
    when ``path`` does not exist)."""
    rows = _report_entries(path, "results", "train-test-gap")
    found: dict[str, dict[str, list]] = {}
    for r in rows or ():
        if r.get("split") == "procedural" and is_shipped(r.get("category"), r.get("weights_sha256")):
            found.setdefault(r["category"], {})[r["instances"]] = r["rot_deg"]
    out = {}
    for cat, by in found.items():
        if "test" in by and "train" in by:
            te, tr = np.asarray(by["test"], dtype=float), np.asarray(by["train"], dtype=float)
            out[cat] = float(np.mean(te / tr))
    return out


def roll_gains(path) -> dict[str, float]:
    """Mean roll gain of each shipped network in a ``roll_equivariance.json`` of ``ancsh bench roll-equivariance``
    (rows labelled by their category and measured on the shipped weights; {} when ``path`` does not exist)."""
    rows = _report_entries(path, "rows", "roll-equivariance")
    return {label: float(r["gain_mean"]) for label, r in (rows or {}).items()
            if label == r.get("category") and is_shipped(label, r.get("weights_sha256"))}


def limit_lines(projections: list[BudgetProjection]) -> list[str]:
    """Markdown: per category, what its targets need, the budget left, and what more of the same training projects."""
    def f(v, spec):
        return "-" if v != v else format(v, spec)

    lines = [
        "| category | rotation must fall to (x today) | budget left (min) | NPCS-curve projection at the budget's end "
        "(x today) | pose-curve exponent | pose-curve projection (x today) | roll gain | rotation, test / training "
        "instances | more of the same training |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for p in projections:
        reach = p.reachable
        verdict = "-" if reach is None else ("met already" if p.needed >= 1.0 else (
            "projected to reach it" if reach else "**projected not to reach it**"))
        lines.append(
            f"| {p.category} | {f(p.needed, '.2f')} | {f(p.left_min, '.0f')} | {f(p.npcs_factor, '.2f')} | "
            f"{f(p.pose_exponent, '.2f')} | {f(p.pose_factor, '.2f')} | {f(p.roll_gain, '.2f')} | "
            f"{f(p.test_over_train, '.2f')} | {verdict} |"
        )
    return lines
