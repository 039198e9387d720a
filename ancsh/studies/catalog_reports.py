"""The reports of the imported objects: ``import_report.md`` of ``ancsh data import`` (:func:`write_import_report`)
and the real objects' measured variation beside the procedural ranges of ``ancsh data ranges``
(:func:`ranges_report`, ``docs/results/category_ranges.md``; tables by :func:`ranges_table`)."""

from __future__ import annotations

from pathlib import Path
from typing import Mapping

from ..data.catalog import Catalog
from ..outputs import write_bytes_atomically

__all__ = ["ranges_report", "ranges_table", "write_import_report"]


def write_import_report(catalog: Catalog, path) -> Path:
    """A markdown table of every object and its outcome (atomic)."""
    from ..data.conventions import rest_diagonal

    lines = [
        "# Import of real objects into the category conventions",
        "",
        f"Produced by `{catalog.command or 'ancsh data import'}`.",
        "",
        "Each object either takes its category's convention (`ancsh.data.conventions`: parts and joints, state 0 "
        "closed / perpendicular measured on the geometry, direction, rest state, NAOCS front, part order, metric "
        "scale) or is rejected with the reason. `zero` is the file's joint value that became the category's "
        "state 0 (file units: radians or the file's length unit).",
        "",
    ]
    counts = {}
    for o in catalog.objects:
        counts.setdefault(o.category, {"train": 0, "test": 0})[o.split] += 1
    lines += ["| category | imported | train | test | rejected |", "|---|---|---|---|---|"]
    rej = {}
    for r in catalog.rejected:
        rej[r.category or "(none)"] = rej.get(r.category or "(none)", 0) + 1
    for cat in sorted(set(counts) | set(rej)):
        c = counts.get(cat, {"train": 0, "test": 0})
        lines.append(f"| {cat} | {c['train'] + c['test']} | {c['train']} | {c['test']} | {rej.get(cat, 0)} |")
    lines += ["", "## Imported", "", "| object | category | split | zero (file) | sign | front turned | scale | rest diagonal (m) | notes |",
              "|---|---|---|---|---|---|---|---|---|"]
    for o in sorted(catalog.objects, key=lambda o: (o.category, o.name)):
        try:
            diag = f"{rest_diagonal(o.model()):.3f}"
        except (ValueError, FileNotFoundError) as exc:
            diag = f"({exc})"
        zero = ", ".join(f"{z:.3f}" for z in o.zero)
        sign = ", ".join(f"{s:+d}" for s in o.sign)
        lines.append(f"| {o.name} | {o.category} | {o.split} | {zero} | {sign} | {'yes' if o.flip_front else 'no'} | "
                     f"{o.scale:.4f} | {diag} | {'; '.join(o.notes)} |")
    lines += ["", "## Rejected", "", "| object | category | reason |", "|---|---|---|"]
    for r in sorted(catalog.rejected, key=lambda r: r.name):
        lines.append(f"| {r.name} | {r.category or '-'} | {r.reason} |")
    path = Path(path)
    write_bytes_atomically(path, ("\n".join(lines) + "\n").encode())
    return path


def ranges_report(catalog: Catalog, *, procedural_instances: int = 60, command: str = "") -> str:
    """Markdown: per category, the real objects' measured variation beside the generator's.

    Real objects are measured after import (metres, canonical orientation, rest state); the
    generator over its first ``procedural_instances`` training instances
    (:func:`ancsh.data.measure.procedural_summary`). Categories without real objects are left out.
    """
    from ..data.conventions import convention
    from ..data.measure import measure_instance, procedural_summary, summarize
    from ..data.procedural import CATEGORIES

    lines = [
        "# Real objects' variation beside the procedural generators'",
        "",
        f"Produced by `{command or 'ancsh data ranges'}`.",
        "",
        "Each category's real objects (every imported object of the catalog, both splits, after import: metres, "
        "NAOCS orientation, rest state) and the generator's first training instances, measured by the same "
        "function (`ancsh.data.measure.measure_instance`, on the geometry). Numbers are `min - max (median)`; "
        "labels are shares. Unitless ratios compare directly; `width`/`height`/`depth`/`diagonal` are metres.",
        "",
    ]
    for category in catalog.categories:
        objs = catalog.instances(category)
        conv = convention(category)
        real = summarize([measure_instance(o.model(), conv) for o in objs])
        columns = {f"real ({len(objs)})": real}
        if category in CATEGORIES:
            columns[f"procedural ({procedural_instances})"] = procedural_summary(category, procedural_instances)
        lines += [f"## {category}", "", ranges_table(columns)]
    return "\n".join(lines)


def _cell(entry) -> str:
    if entry is None:
        return "-"
    if "shares" in entry:
        return ", ".join(f"{k} {100 * f:.0f} %" for k, f in entry["shares"].items())
    return f"{entry['min']:.3g} - {entry['max']:.3g} ({entry['median']:.3g})"


def ranges_table(summaries: Mapping[str, Mapping]) -> str:
    """A Markdown table with one row per measured key and one column per summary.

    Parameters
    ----------
    summaries : mapping of str to dict
        Column label (e.g. ``"real (15)"``, ``"procedural (200)"``) -> :func:`summarize` result.

    Returns
    -------
    str
        Numbers as ``min - max (median)``, labels as their shares; ``-`` where a column lacks a key.
    """
    if not summaries:
        raise ValueError("summaries: need at least one column")
    keys = list(dict.fromkeys(k for s in summaries.values() for k in s))
    lines = ["| measurement | " + " | ".join(summaries) + " |", "|---" * (len(summaries) + 1) + "|"]
    lines += [f"| {k} | " + " | ".join(_cell(s.get(k)) for s in summaries.values()) + " |" for k in keys]
    return "\n".join(lines) + "\n"
