"""Catalogs of imported real objects: build, save, load, preview and report.

A catalog is one JSON file (``catalog.json``) listing :class:`~ancsh.data.importer.ImportedObject`
records and the rejected objects with their reasons. It refers to the URDF files (under the
shared data folder with a ``shared:`` prefix) and copies no mesh. The package ships one built
from ``../shared/data/partnet_mobility`` (:func:`builtin_catalog_path`); ``ancsh data import``
builds others.

``ancsh data import`` writes, into its ``--out`` folder: ``catalog.json``, ``import_report.md``
(a table of every object and its outcome) and ``previews/<category>.png`` (per object the rest
and a moved state, NAOCS axes and part names, so a person checks a catalog at a glance).
"""

from __future__ import annotations

import io
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..outputs import write_bytes_atomically
from .importer import ImportedObject, ImportRejected, _guess_category, _object_name, assign_splits, import_object

__all__ = [
    "Catalog",
    "Rejection",
    "build_catalog",
    "builtin_catalog_path",
    "draw_preview_sheet",
    "load_catalog",
    "write_bytes_atomically",
    "write_catalog",
]

CATALOG_VERSION = 1


@dataclass(frozen=True)
class Rejection:
    """An object that is not imported, and why."""

    name: str
    category: str | None
    reason: str

    def to_dict(self) -> dict:
        return {"name": self.name, "category": self.category, "reason": self.reason}


@dataclass(frozen=True)
class Catalog:
    """Imported objects and rejections.

    Attributes
    ----------
    objects : tuple of ImportedObject
    rejected : tuple of Rejection
    command : str
        The command that built it.
    """

    objects: tuple
    rejected: tuple = ()
    command: str = ""

    def instances(self, category: str, split: str | None = None) -> tuple:
        """Imported objects of ``category`` (and of ``split`` when given), by name."""
        if split not in (None, "train", "test"):
            raise ValueError(f"split: expected 'train', 'test' or None, got {split!r}")
        return tuple(sorted((o for o in self.objects if o.category == category and (split is None or o.split == split)),
                            key=lambda o: o.name))

    @property
    def categories(self) -> tuple:
        return tuple(sorted({o.category for o in self.objects}))

    def to_dict(self) -> dict:
        return {
            "version": CATALOG_VERSION,
            "command": self.command,
            "objects": [o.to_dict() for o in sorted(self.objects, key=lambda o: o.name)],
            "rejected": [r.to_dict() for r in sorted(self.rejected, key=lambda r: r.name)],
        }


def builtin_catalog_path() -> Path:
    """The catalog shipped with the package (the shared PartNet-Mobility objects)."""
    return Path(__file__).resolve().parent / "catalogs" / "partnet_mobility.json"


def load_catalog(path=None) -> Catalog:
    """Read a catalog file (default: :func:`builtin_catalog_path`)."""
    path = builtin_catalog_path() if path is None else Path(path)
    if path.is_dir():
        path = path / "catalog.json"
    try:
        data = json.loads(path.read_text())
    except FileNotFoundError:
        raise ValueError(f"catalog: no catalog file {path}") from None
    except (OSError, ValueError) as exc:
        raise ValueError(f"catalog: cannot read {path}: {exc}") from None
    if not isinstance(data, dict) or data.get("version") != CATALOG_VERSION:
        raise ValueError(f"catalog: {path} is not an ancsh catalog (version {CATALOG_VERSION})")
    objects = tuple(ImportedObject.from_dict(d, str(path)) for d in data.get("objects", []))
    rejected = tuple(Rejection(str(d["name"]), d.get("category"), str(d["reason"])) for d in data.get("rejected", []))
    return Catalog(objects, rejected, str(data.get("command", "")))


def _urdfs(paths) -> list[Path]:
    out = []
    for p in paths:
        p = Path(p)
        if p.is_dir() and (p / "mobility.urdf").is_file():
            out.append(p / "mobility.urdf")
        elif p.is_dir():
            found = sorted(p.glob("*/mobility.urdf")) + sorted(q for q in p.glob("*.urdf"))
            if not found:
                raise ValueError(f"paths: folder {p} holds no URDF objects")
            out.extend(found)
        elif p.is_file():
            out.append(p)
        elif p.exists():
            raise ValueError(f"paths: {p} exists but is neither a URDF file nor a folder of URDF objects")
        else:
            raise ValueError(f"paths: {p} does not exist")
    unique, seen = [], {}
    for urdf in out:  # a path given twice (or inside a folder also given) is imported once
        key = urdf.resolve()
        if key not in seen:
            seen[key] = urdf
            unique.append(urdf)
    by_name = {}
    for urdf in unique:  # two different objects of one name would be one catalog entry twice
        other = by_name.setdefault(_object_name(urdf), urdf)
        if other is not urdf:
            raise ValueError(f"paths: {other} and {urdf} are both object {_object_name(urdf)!r}; import them apart")
    return unique


def build_catalog(paths, category: str | None = None, *, overrides: dict | None = None, command: str = "",
                  progress=None) -> Catalog:
    """Import every object under ``paths`` (URDF files, object folders or folders of them).

    Parameters
    ----------
    paths : sequence of str or Path
    category : str, optional
        Import everything into this category (default: each object's own, from its metadata).
    overrides : dict, optional
        ``{object name: override}`` (:func:`~ancsh.data.importer.load_overrides`); an override
        naming an object that is not imported is an error.
    progress : callable, optional
        Called with each object's name before it is imported.

    Objects the category cannot hold (:class:`~ancsh.data.importer.ImportRejected`) and broken
    files (malformed XML, missing meshes: ``unreadable: ...``) are listed in ``rejected`` with
    the reason; the others are imported. A file reached twice (the same folder given twice) is
    imported once; two different files of one object name are an error.
    """
    urdfs = _urdfs(paths)
    overrides = dict(overrides or {})
    names = {_object_name(u) for u in urdfs}
    unknown = sorted(set(overrides) - names)
    if unknown:
        raise ValueError(f"override: names object(s) {unknown} that are not among the imported paths")
    objects, rejected = [], []
    for urdf in urdfs:
        name = _object_name(urdf)
        if progress is not None:
            progress(name)
        try:
            objects.append(import_object(urdf, category, override=overrides.get(name)))
        except ImportRejected as exc:
            rejected.append(Rejection(name, category or _guess_category(urdf), exc.reason))
        except ValueError as exc:  # a broken file: recorded with the loader's message, the others go on
            rejected.append(Rejection(name, category or _guess_category(urdf), f"unreadable: {exc}"))
    return Catalog(tuple(assign_splits(objects)), tuple(rejected), command)


def write_catalog(catalog: Catalog, path) -> Path:
    """Write ``catalog`` as JSON (atomically: a failed write leaves no half file)."""
    path = Path(path)
    write_bytes_atomically(path, (json.dumps(catalog.to_dict(), indent=1) + "\n").encode())
    return path


def _open_states(model) -> np.ndarray:
    """A clearly moved state: each joint 60 % of the way from rest to its far limit."""
    q = model.rest_states.copy()
    for k, j in enumerate(model.joints):
        hi = j.upper if np.isfinite(j.upper) else j.rest + np.pi / 2
        lo = j.lower if np.isfinite(j.lower) else j.rest - np.pi / 2
        far = hi if hi - j.rest >= j.rest - lo else lo
        q[k] = j.rest + 0.6 * (far - j.rest)
    return q


def draw_preview_sheet(objects, out, *, title: str = "", points_per_part: int = 300, seed: int = 0) -> Path:
    """One picture of many imported objects: per object its rest state and a moved one (60 % towards the far limit) in NAOCS
    orientation (x right, z front, y up), parts coloured and named, canonical axes drawn.

    Parameters
    ----------
    objects : sequence of ImportedObject
    out : str or Path
        PNG file (written atomically).
    """
    from matplotlib import colormaps
    from matplotlib.figure import Figure

    from ..model.articulated import sample_surface

    objects = list(objects)
    if not objects:
        raise ValueError("objects: nothing to draw")
    rng = np.random.default_rng(seed)
    cols = 4  # two objects per row, two panels each
    rows = (2 * len(objects) + cols - 1) // cols
    fig = Figure(figsize=(4 * cols, 3.6 * rows + 0.6), dpi=55)
    if title:
        fig.suptitle(title, fontsize=14)
    cmap = colormaps["tab10"]
    for i, obj in enumerate(objects):
        model = obj.model()
        for j, (label, q) in enumerate((("rest", model.rest_states), ("moved", _open_states(model)))):
            ax = fig.add_subplot(rows, cols, 2 * i + j + 1, projection="3d")
            poses = model.forward_kinematics(q)
            R = model.R_canon_base
            allp = []
            for p_idx, part in enumerate(model.parts):
                pts = poses[p_idx].apply(sample_surface(part.mesh, points_per_part, rng)) @ R.T
                allp.append(pts)
                ax.scatter(pts[:, 0], pts[:, 2], pts[:, 1], s=1, color=cmap(p_idx % 10), label=part.name, depthshade=False)
            allp = np.concatenate(allp)
            c = 0.5 * (allp.min(axis=0) + allp.max(axis=0))
            r = 0.5 * float(np.max(allp.max(axis=0) - allp.min(axis=0)))
            for axis_vec, col, name in ((np.eye(3)[0], "r", "x"), (np.eye(3)[2], "b", "z front"), (np.eye(3)[1], "g", "y up")):
                e = c + 0.8 * r * axis_vec
                ax.plot([c[0], e[0]], [c[2], e[2]], [c[1], e[1]], color=col, lw=1.5)
                ax.text(e[0], e[2], e[1], name, color=col, fontsize=7)
            ax.set_xlim(c[0] - r, c[0] + r)
            ax.set_ylim(c[2] - r, c[2] + r)
            ax.set_zlim(c[1] - r, c[1] + r)
            ax.set_box_aspect((1, 1, 1))
            ax.view_init(elev=20, azim=-60)
            ax.set_xticks([])
            ax.set_yticks([])
            ax.set_zticks([])
            states = ", ".join(f"{v:.2f}" for v in q)
            ax.set_title(f"{obj.name} ({obj.split}) {label}\nq=[{states}]", fontsize=8)
            if j == 0:
                ax.legend(loc="lower left", fontsize=6, markerscale=5, frameon=False)
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    out = Path(out)
    write_bytes_atomically(out, buf.getvalue())
    return out
