"""Procedural articulated objects: the ANCSH paper's five categories, two side-hinged door categories and boxes.

``make_object(category, seed)`` builds one instance, deterministically from the seed, in the
canonical orientation shared by all categories: +y up, +z towards the object's front (the
side a user faces), +x to the right; part 0 is the base and joints follow the paper's part
table. ``instance_seeds(category, split)`` gives the fixed, disjoint train/test instances.

===============  ==============================================  ===================================================
category         parts (label order)                             joints (state meaning; rest)
===============  ==============================================  ===================================================
eyeglasses       base (front frame), left_temple, right_temple   2 revolute, vertical (fold; rest 0 = right angles)
oven             base, door                                      1 revolute, bottom or side hinge (opening; rest 0 closed)
washing_machine  base, door                                      1 revolute, left side hinge or a top lid's back or side edge (opening; rest 0 closed)
laptop           base, display                                   1 revolute (opening; rest pi/2 upright)
drawer           base, lowest, middle, top                       3 prismatic, +z (pull-out; rest 0 closed)
microwave        base, door                                      1 revolute, left or right side hinge (opening; rest 0 closed)
safe             base, door                                      1 revolute, right or left side hinge (opening; rest 0 closed)
box              base, lid                                       1 revolute, the top's back edge (opening; rest 0 closed)
===============  ==============================================  ===================================================

Each generator's docstring lists its shape variants and their probabilities (door and hinge
variants, drawer layouts, temple shapes, proportions calibrated on the PartNet-Mobility
objects); :mod:`ancsh.data.measure` measures them. The variants of issue #11 changed the
instances of every seed of the paper's categories (the seeds and the split are unchanged), so
datasets generated before them differ from those generated now; :func:`generator_version` gives each
category's version.

:data:`CATEGORIES` lists every procedural category; :data:`PAPER_CATEGORIES` the paper's five,
the ones with shipped weights, the demo and the published evaluations (``microwave``, ``safe``
and ``box`` are beyond the paper: ``CategoryConvention.in_paper`` is false).

Left/right are as seen from the front (+z): the left temple is at -x.
:data:`CATEGORY_INFO` gives part/joint names and types and the rest-state size range.
"""

from __future__ import annotations

from types import MappingProxyType

from ...model.articulated import ArticulatedModel
from . import box, drawer, eyeglasses, laptop, microwave, oven, safe, washing_machine
from .registry import NUM_TEST, NUM_TRAIN, SPLITS, CategoryInfo, category_rng, split_seeds

_MODULES = {
    "eyeglasses": eyeglasses,
    "oven": oven,
    "washing_machine": washing_machine,
    "laptop": laptop,
    "drawer": drawer,
    "microwave": microwave,
    "safe": safe,
    "box": box,
}

#: Every procedural category, the paper's five first.
CATEGORIES = tuple(_MODULES)

#: Version of each category's generator shapes: 1 = the first five categories; 2 = issue #11's variants
#: and microwave / safe (the box category was added at 2: no other category's instances changed);
#: 3 = the washing machine's side-hinged top loaders (issue #35; its other instances are unchanged).
#: Stored in every dataset's settings, evaluation report and template library stamp: a dataset made by
#: other generators is never resumed with these (its seeds would give other shapes), and a report of
#: other shapes reads as stale. Per category, so that a change to one generator stales only its own.
GENERATOR_VERSIONS = MappingProxyType({c: 3 if c == "washing_machine" else 2 for c in CATEGORIES})

#: The ANCSH paper's five categories (shipped weights, ``ancsh demo``, published evaluations).
PAPER_CATEGORIES = tuple(c for c in CATEGORIES if _MODULES[c].INFO.in_paper)

#: ``CATEGORY_INFO[category]`` -> :class:`CategoryInfo` (part/joint names, types, sizes).
CATEGORY_INFO = MappingProxyType({c: _MODULES[c].INFO for c in CATEGORIES})


def generator_version(category: str) -> int | None:
    """The version of ``category``'s generator shapes (:data:`GENERATOR_VERSIONS`); ``None`` for a category from a
    spec file without a generator (its shapes are its imported objects').

    Raises
    ------
    ValueError
        For an unknown category.
    """
    if category not in _MODULES:
        from ..conventions import CONVENTIONS

        if isinstance(category, str) and category in CONVENTIONS:
            return None
    return GENERATOR_VERSIONS[_check_category(category)]


def _check_category(category) -> str:
    if category not in _MODULES:
        raise ValueError(f"category: expected one of {CATEGORIES}, got {category!r}")
    return category


def make_object(category: str, seed: int) -> ArticulatedModel:
    """Instance ``seed`` of ``category``, identical for the same arguments.

    Parameters
    ----------
    category : str
        One of :data:`CATEGORIES`.
    seed : int
        Non-negative instance seed (see :func:`instance_seeds` for the split).

    Returns
    -------
    ArticulatedModel
        Meshes in metres in each part's frame; the base frame is canonical
        (``R_canon_base`` = identity); named ``"<category>_<seed>"``.
    """
    category = _check_category(category)
    rng = category_rng(category, seed)
    return _MODULES[category].build(rng, f"{category}_{int(seed)}")


def instance_seeds(category: str, split: str) -> tuple[int, ...]:
    """Seeds of the ``"train"`` or ``"test"`` instances of ``category`` (disjoint, fixed)."""
    _check_category(category)
    return split_seeds(split)


def load_instance(category: str, split: str, index: int) -> ArticulatedModel:
    """The ``index``-th instance of ``split`` of ``category``."""
    seeds = instance_seeds(category, split)
    if isinstance(index, bool) or not isinstance(index, int) or not 0 <= index < len(seeds):
        raise ValueError(f"index: expected an int in [0, {len(seeds)}) for split {split!r}, got {index!r}")
    return make_object(category, seeds[index])


__all__ = [
    "CATEGORIES",
    "CATEGORY_INFO",
    "GENERATOR_VERSIONS",
    "NUM_TEST",
    "NUM_TRAIN",
    "PAPER_CATEGORIES",
    "SPLITS",
    "CategoryInfo",
    "generator_version",
    "instance_seeds",
    "load_instance",
    "make_object",
]
