"""One category, resolved once: its spec, networks, calibrations, template and limits (issue 62).

:func:`load_category` turns what a user gives -- a built-in name, a spec file, a built category folder (registered,
:func:`~ancsh.data.conventions.register_category`), or a :class:`Category` already loaded -- into a
:class:`Category`, checks it and reads its calibrations. The entry points (:func:`ancsh.predict`,
:func:`~ancsh.learned.inference.predict.predict_depth`, the trackers, the service) call it once; everything below them
takes the :class:`Category` or the pieces of it they need (the isolation its size range, the checks its convention,
render-and-compare its template), never a name to look up.

The template library is the one piece read on first use (building it from a generator takes seconds) and kept.
"""

from __future__ import annotations

import json
import threading
from dataclasses import dataclass, field
from pathlib import Path

from ...data.category_types import CategoryConvention

__all__ = ["Category", "DEFAULT_SIZE_RANGE", "load_category"]

#: ``(lo, hi)`` metres of the box diagonal of a category without a convention (a network named for no known category).
DEFAULT_SIZE_RANGE = (0.1, 2.0)


@dataclass(frozen=True, eq=False)
class Category:
    """Everything a prediction needs of one category, loaded and checked once (:func:`load_category`).

    Attributes
    ----------
    name : str
        The category's name (its spec's ``name``; a network's own category name where it has no convention).
    convention : CategoryConvention or None
        Its spec: parts, joints (types, rest states, ranges), size range, viewpoint; ``None`` for a name without one.
    weights_dir : Path
        Where its networks and calibrations are: a built category's folder, else the shipped weights folder.
    size_range : (float, float)
        Rest-state box diagonal of real instances, metres (the spec's ``diagonal_m``;
        :data:`DEFAULT_SIZE_RANGE` without a convention).
    p_good_calibration : dict or None
        ``<name>_confidence.json`` (:mod:`ancsh.learned.inference.confidence`), read at load; ``None`` without one.
    p_object_calibration : dict or None
        ``<name>_object.json``, read at load; ``None`` without one.
    refine_default : str or None
        What ``refine="auto"`` does for it (:func:`ancsh.data.templates.refine_default`).
    """

    name: str
    convention: CategoryConvention | None = field(repr=False)
    weights_dir: Path
    size_range: tuple
    p_good_calibration: dict | None = field(default=None, repr=False)
    p_object_calibration: dict | None = field(default=None, repr=False)
    refine_default: str | None = None
    _template: list = field(default_factory=list, init=False, repr=False)  # [TemplateLibrary] once read
    _lock: object = field(default_factory=threading.Lock, init=False, repr=False)

    @property
    def typical_size(self) -> float:
        """Typical box diagonal, metres: the convention's (geometric mean of its range), else of :attr:`size_range`."""
        if self.convention is not None:
            return self.convention.typical_size
        lo, hi = self.size_range
        return float((lo * hi) ** 0.5)

    def weights_path(self, kind: str = "ancsh") -> Path:
        """``<name>.pt`` (``<name>_<kind>.pt`` for the other networks: ``refine``, baselines) in :attr:`weights_dir`."""
        from ..network.weights import weights_file_name

        return self.weights_dir / weights_file_name(self.name, kind)

    def template_library(self):
        """The category's :class:`~ancsh.data.templates.TemplateLibrary`, read (or built) on first use and kept;
        ``ValueError`` for a category without templates."""
        with self._lock:
            if not self._template:
                from ...data.templates import load_template_library

                self._template.append(load_template_library(self.name))
            return self._template[0]

    def has_templates(self) -> bool:
        """Whether the category has a template library (a convention: built-in or built from a spec)."""
        return self.convention is not None

    def inflation(self, providers, weights_sha256: str | None):
        """The measured uncertainty :class:`~ancsh.solvers.uncertainty.Inflation` of the first of ``providers``
        measured for these weights of this category (identity where none is)."""
        from ...solvers.uncertainty import first_measured_inflation

        return first_measured_inflation(providers, self.name, weights_sha256=weights_sha256)

    def names(self, num_parts: int, num_joints: int) -> tuple[tuple, tuple]:
        """``(part names, joint names)`` of a network of ``num_parts`` parts and ``num_joints`` joints: the
        convention's where they match its structure, else ``part0``..., ``joint0``...."""
        conv = self.convention
        if conv is not None and len(conv.part_names) == num_parts and len(conv.joint_names) == num_joints:
            return tuple(conv.part_names), tuple(conv.joint_names)
        return tuple(f"part{j}" for j in range(num_parts)), tuple(f"joint{k}" for k in range(num_joints))

    def rest_states(self, num_joints: int) -> tuple[tuple, str]:
        """``(rest state per joint, rad or m; NaN when unknown, their description)``."""
        conv = self.convention
        if conv is None or len(conv.joints) != num_joints:
            return tuple([float("nan")] * num_joints), "unknown category: rest states unknown"
        return tuple(float(q) for q in conv.rest_states), conv.rest_description


def _read_calibration(path: Path) -> dict | None:
    """The calibration JSON at ``path``, ``None`` where there is none."""
    return json.loads(path.read_text()) if path.is_file() else None


def load_category(category, *, network_category: str | None = None) -> Category:
    """The :class:`Category` of a user's ``category``: checked, its calibrations read.

    Parameters
    ----------
    category : str, Path, CategoryConvention or Category
        A known name, a spec file or built category folder (registered for this process and the ones it starts), a
        convention, or a :class:`Category` (returned as it is).
    network_category : str, optional
        Allow a name without a convention (a network's own category, e.g. a test network): it gets
        :data:`DEFAULT_SIZE_RANGE` and no templates. Without it such a name is refused.

    Raises
    ------
    FileNotFoundError
        A name that is no category (:func:`~ancsh.learned.network.weights.missing_weights_error`: the categories that
        have networks).
    ValueError
        A wrong spec (naming its file and key), or not a category at all.
    """
    if isinstance(category, Category):
        return category
    from ...data.conventions import CONVENTIONS, is_category_path, resolve_category
    from ...data.templates import refine_default
    from ..network.weights import missing_weights_error, weights_dir
    from .confidence import calibration_path, object_calibration_path

    if isinstance(category, str) and category not in CONVENTIONS and not is_category_path(category):
        if category != network_category:
            raise missing_weights_error(category)
        name, conv = category, None
    else:
        name = resolve_category(category)
        conv = CONVENTIONS[name]
    return Category(name=name, convention=conv, weights_dir=weights_dir(name),
                    size_range=DEFAULT_SIZE_RANGE if conv is None else tuple(conv.diagonal_range),
                    p_good_calibration=_read_calibration(calibration_path(name)),
                    p_object_calibration=_read_calibration(object_calibration_path(name)),
                    refine_default=refine_default(name))
