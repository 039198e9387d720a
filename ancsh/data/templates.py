"""Category template libraries: the training instances of a category, summarised by their part boxes.

A category template is a training instance (procedural, or an imported real object of the
train split) used as a stand-in CAD model when refining a learned fit by articulated ICP
(:mod:`ancsh.solvers.icp.category`). Choosing one needs only each instance's part boxes in
NAOCS, so a library stores those (a few numbers per instance) and rebuilds the one chosen
model on demand (procedural instances from their seed, real ones from their URDF).

Libraries are built once per category (:func:`build_template_library`, about 25 s for the 200
procedural training instances) and kept as JSON in ``ancsh/data/templates/<category>.json``
(:func:`load_template_library` reads it in milliseconds; a missing or stale file -- other
generator version or catalog -- is rebuilt in memory).
"""

from __future__ import annotations

import functools
import hashlib
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..geometry._checks import as_array

__all__ = [
    "LIBRARY_VERSION",
    "TemplateEntry",
    "TemplateLibrary",
    "build_template_library",
    "library_path",
    "load_template_library",
    "refine_default",
    "write_template_library",
]

LIBRARY_VERSION = 1


@dataclass(frozen=True)
class TemplateEntry:
    """One training instance of a category, by its part boxes in NAOCS (joints at rest).

    Attributes
    ----------
    name : str
        Instance name (``"<category>_<seed>"`` for procedural instances, the object name for real ones).
    source : str
        ``"procedural"`` or ``"real"``.
    seed : int or None
        Procedural instance seed (``None`` for real objects).
    centres : (M, 3) float64
        Part box centres in NAOCS (object box diagonal 1).
    sizes : (M, 3) float64
        Part box side lengths in NAOCS.
    metres_per_unit : float
        The instance's size: metres per NAOCS unit (its object box diagonal).
    """

    name: str
    source: str
    seed: int | None
    centres: np.ndarray
    sizes: np.ndarray
    metres_per_unit: float

    def __post_init__(self):
        if self.source not in ("procedural", "real"):
            raise ValueError(f"source: expected 'procedural' or 'real', got {self.source!r}")
        c = as_array(self.centres, "centres", (None, 3))
        object.__setattr__(self, "centres", c)
        object.__setattr__(self, "sizes", as_array(self.sizes, "sizes", (c.shape[0], 3)))

    def to_dict(self) -> dict:
        return {"name": self.name, "source": self.source, "seed": self.seed,
                "centres": np.round(self.centres, 6).tolist(), "sizes": np.round(self.sizes, 6).tolist(),
                "metres_per_unit": round(float(self.metres_per_unit), 6)}

    @classmethod
    def from_dict(cls, d: dict) -> "TemplateEntry":
        return cls(str(d["name"]), str(d["source"]), None if d.get("seed") is None else int(d["seed"]),
                   np.asarray(d["centres"], dtype=float), np.asarray(d["sizes"], dtype=float), float(d["metres_per_unit"]))

    @classmethod
    def of_model(cls, model, source: str, seed: int | None = None) -> "TemplateEntry":
        """The entry of an :class:`~ancsh.model.articulated.ArticulatedModel` (its canonical part boxes)."""
        from ..model.canonical import canonical_space

        cs = canonical_space(model)
        sizes = cs.npcs_scale[:, None] * cs.npcs_extents
        return cls(model.name, source, seed, np.array(cs.npcs_translation), sizes, 1.0 / cs.T_naocs_base.scale)


class TemplateLibrary:
    """The template entries of one category, with nearest-box selection and the models on demand.

    Parameters
    ----------
    category : str
    entries : sequence of TemplateEntry
        At least one; all with the same part count.
    real : str or None
        The catalog the real entries came from (``"builtin"`` or a path), if any.
    stamp : dict
        What the entries were built from (generator version, catalog hash): a library whose
        stamp differs from :func:`_stamp` of the current code is stale.
    """

    def __init__(self, category: str, entries, real: str | None = None, stamp: dict | None = None):
        entries = tuple(entries)
        if not entries:
            raise ValueError(f"entries: the template library of {category!r} is empty")
        if not all(isinstance(e, TemplateEntry) for e in entries):
            raise ValueError("entries: expected TemplateEntry objects")
        M = {e.centres.shape[0] for e in entries}
        if len(M) != 1:
            raise ValueError(f"entries: instances of {category!r} differ in part count {sorted(M)}")
        self.category = category
        self.entries = entries
        self.real = real
        self.stamp = dict(stamp or {})
        self.num_parts = M.pop()
        self._features = np.stack([np.concatenate([e.sizes.ravel(), e.centres.ravel()]) for e in entries])
        self._models: dict = {}
        self._available: dict = {}

    def __len__(self) -> int:
        return len(self.entries)

    def nearest(self, centres, sizes, *, count: int = 1) -> list[int]:
        """Indices of the ``count`` :meth:`available` entries whose part boxes are nearest to the given ones
        (fewer where fewer are available; none without any).

        Distance: Euclidean over every part's box side lengths and centre (NAOCS units, so the
        object's overall size does not matter; a template is scaled to the fitted boxes anyway).

        Parameters
        ----------
        centres, sizes : (M, 3) array_like
            Part box centres and side lengths in NAOCS, in part order.
        count : int
            How many, nearest first.
        """
        c = as_array(centres, "centres", (self.num_parts, 3))
        s = as_array(sizes, "sizes", (self.num_parts, 3))
        if isinstance(count, bool) or int(count) != count or count < 1:
            raise ValueError(f"count: expected a positive integer, got {count!r}")
        f = np.concatenate([s.ravel(), c.ravel()])
        d = np.linalg.norm(self._features - f, axis=1)
        order = [int(i) for i in np.argsort(d, kind="stable") if self.available(int(i))]
        return order[: int(count)]

    def available(self, index: int) -> bool:
        """Whether entry ``index`` can be built here: procedural entries always; real ones when their
        URDF is present (the shared data folder, :func:`ancsh.data.paths.shared_data_dir`). Checked once
        per entry. :meth:`nearest` returns available entries only, so a library stays usable (with its
        procedural entries) on a machine without the shared data."""
        if index not in self._available:
            e = self.entries[index]
            if e.source == "procedural":
                self._available[index] = True
            else:
                obj = _real_objects(self.real or "builtin", self.category).get(e.name)
                self._available[index] = obj is not None and obj.urdf_path.is_file()
        return self._available[index]

    #: Triangle budget per part of a template model (larger real meshes are decimated once, on load).
    MAX_FACES = 3000

    def model(self, index: int):
        """The :class:`~ancsh.model.articulated.ArticulatedModel` of entry ``index`` (built once, kept;
        parts of more than :attr:`MAX_FACES` triangles decimated)."""
        if isinstance(index, bool) or not isinstance(index, (int, np.integer)) or not 0 <= index < len(self.entries):
            raise ValueError(f"index: expected an entry index in [0, {len(self.entries)}), got {index!r}")
        index = int(index)
        if index not in self._models:
            e = self.entries[index]
            if e.source == "procedural":
                from .procedural import make_object

                model = make_object(self.category, e.seed)
            else:
                model = _real_objects(self.real or "builtin", self.category)[e.name].model()
            from ..model.edit import simplified

            self._models[index] = simplified(model, self.MAX_FACES)
        return self._models[index]

    def to_dict(self) -> dict:
        return {"version": LIBRARY_VERSION, "category": self.category, "real": self.real, "stamp": self.stamp,
                "entries": [e.to_dict() for e in self.entries]}

    @classmethod
    def from_dict(cls, d: dict) -> "TemplateLibrary":
        if not isinstance(d, dict) or d.get("version") != LIBRARY_VERSION:
            raise ValueError(f"library: not an ancsh template library (version {LIBRARY_VERSION})")
        return cls(str(d["category"]), [TemplateEntry.from_dict(e) for e in d["entries"]], d.get("real"), d.get("stamp"))


def _real_objects(real: str, category: str) -> dict:
    from .catalog import load_catalog

    catalog = load_catalog(None if real == "builtin" else real)
    return {o.name: o for o in catalog.instances(category, "train")}


def _stamp(category: str, real: str | None) -> dict:
    """What a library of ``category`` depends on: the generators' version and the catalog's bytes."""
    from .catalog import builtin_catalog_path
    from .procedural import CATEGORIES, NUM_TRAIN, generator_version

    stamp = {"generator_version": generator_version(category),  # None without a generator
             "procedural_instances": NUM_TRAIN if category in CATEGORIES else 0, "catalog_sha256": None}
    if real is not None:
        path = builtin_catalog_path() if real == "builtin" else Path(real)
        path = path / "catalog.json" if path.is_dir() else path
        stamp["catalog_sha256"] = hashlib.sha256(path.read_bytes()).hexdigest()
    return stamp


def build_template_library(category: str, *, real: str | None = "builtin", progress: bool = False) -> TemplateLibrary:
    """Every training instance of ``category``: the procedural train split and, with ``real``,
    the train split of that catalog's imported objects (``"builtin"`` = the shipped catalog).

    Real objects whose URDF cannot be read here (shared data absent) are left out.

    A category without a procedural generator (from a spec) holds its catalog's objects only; for a built
    category, ``real="builtin"`` means its folder's ``catalog.json``.

    Raises
    ------
    ValueError
        For an unknown category, or a spec category without a catalog object in the train split.
    """
    from .conventions import convention
    from .procedural import CATEGORIES, instance_seeds, make_object

    convention(category)  # a known category, or the error naming the known ones
    real = _own_catalog(category, real)
    seeds = instance_seeds(category, "train") if category in CATEGORIES else ()
    entries = []
    it = seeds
    if progress:
        from tqdm import tqdm

        it = tqdm(seeds, desc=f"templates {category}", unit="instance")
    for seed in it:
        entries.append(TemplateEntry.of_model(make_object(category, seed), "procedural", seed))
    if real is not None:
        for name, obj in sorted(_real_objects(real, category).items()):
            try:
                model = obj.model()
            except (OSError, ValueError):  # the URDF or its meshes are not here
                continue
            entries.append(TemplateEntry.of_model(model, "real"))
    if not entries:
        raise ValueError(f"category: {category!r} has no procedural generator and its catalog {real!r} no object of "
                         "the train split that can be read here: no template to build")
    return TemplateLibrary(category, entries, real, _stamp(category, real))


def _own_catalog(category: str, real: str | None) -> str | None:
    """``real``, with ``"builtin"`` meaning a built category's own ``catalog.json``."""
    from .conventions import category_folder

    folder = category_folder(category)
    if real == "builtin" and folder is not None:
        return str(folder / "catalog.json")
    return real


def library_path(category: str) -> Path:
    """Where the library of ``category`` lives: ``ancsh/data/templates/<category>.json`` for a built-in
    category, ``template.json`` in a built category's folder."""
    from .conventions import category_folder

    folder = category_folder(category)
    if folder is not None:
        return folder / "template.json"
    return Path(__file__).resolve().parent / "templates" / f"{category}.json"


def write_template_library(library: TemplateLibrary, path=None) -> Path:
    """Write ``library`` as JSON (default :func:`library_path`)."""
    path = library_path(library.category) if path is None else Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(library.to_dict(), separators=(",", ":")) + "\n")
    return path


@functools.lru_cache(maxsize=16)
def load_template_library(category: str, real: str | None = "builtin") -> TemplateLibrary:
    """The template library of ``category`` (cached per process).

    Reads the shipped file when it matches the current generators and catalog (its stamp), else
    builds the library in memory (:func:`build_template_library`, about 25 s).
    """
    real = _own_catalog(category, real)
    path = library_path(category)
    if path.is_file():
        try:
            lib = TemplateLibrary.from_dict(json.loads(path.read_text()))
        except (ValueError, KeyError, TypeError):
            lib = None
        if lib is not None and lib.category == category and lib.real == real and lib.stamp == _stamp(category, real):
            return lib
    return build_template_library(category, real=real)


def refine_default(category: str) -> str | None:
    """What ``refine="auto"`` does for ``category``: ``"template"`` (refine against the category template),
    ``"network"`` (the refinement network) or ``None`` (no refinement).

    Read from ``ancsh/data/templates/refine_defaults.json``, written by ``ancsh bench refine-defaults
    --install`` from each category's full evaluation (``ancsh evaluate --refine template network``, e.g.
    ``docs/results/<category>.md``; the rule: :data:`ancsh.studies.refinement.HELPS_RULE`). Unknown categories:
    ``None``. (A file of the earlier form, ``true`` / ``false`` per category, reads as ``"template"`` / ``None``.)
    """
    path = Path(__file__).resolve().parent / "templates" / "refine_defaults.json"
    try:
        data = json.loads(path.read_text())
    except FileNotFoundError:
        return None
    choice = data.get("categories", {}).get(category)
    if choice is True:
        return "template"
    return choice if choice in ("template", "network") else None
