"""Every object of the category in a frame: the verified candidates of ``ancsh predict`` made into an object list.

Isolation (:func:`ancsh.data.isolate.isolate_object`) proposes candidate segments from every depth of plane removal,
so one object can come back several times (a box with and without the stair tread under it, its lid alone) and two
objects can share pixels (segments that touch). :func:`select_objects` keeps, best supported first, every candidate
whose fit passed its checks and that is not mostly a candidate already kept (:data:`SAME_OBJECT_SHARE` of its
pixels), and gives each pixel to the best-supported object that claims it: two objects' masks never share a pixel.

:func:`mask_rle` / :func:`rle_mask` write and read an object's pixel mask as a row-major run-length code (the JSON's
``mask`` record, ``docs/json_schema.md``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["SAME_OBJECT_SHARE", "ObjectCandidate", "mask_bbox", "mask_rle", "rle_mask", "same_object",
           "select_objects"]

#: A passed candidate that has at least this share of its pixels in an object already kept is that object again.
SAME_OBJECT_SHARE = 0.5


@dataclass(frozen=True)
class ObjectCandidate:
    """One object of the list: the candidate segment it came from (``None``: a user's mask or every pixel), its fit
    and evidence (:func:`~ancsh.learned.inference.candidate.fit_candidate`'s dict) and its pixels ``(H, W)`` bool."""

    segment: int | None
    attempt: dict
    mask: np.ndarray


def same_object(mask, kept_masks) -> bool:
    """Whether at least :data:`SAME_OBJECT_SHARE` of ``mask``'s pixels lie in one of ``kept_masks`` (``(H, W)`` bool
    each)."""
    m = np.asarray(mask, dtype=bool)
    n = max(int(np.count_nonzero(m)), 1)
    return any(np.count_nonzero(m & k) >= SAME_OBJECT_SHARE * n for k in kept_masks)


def select_objects(candidates, score, *, max_objects: int | None = None) -> list:
    """The object list from verified candidates (module docstring).

    Parameters
    ----------
    candidates : sequence of ObjectCandidate
        Every fitted candidate, passed or not.
    score : callable
        ``attempt -> float``: how well a candidate's fit is supported (higher first).
    max_objects : int, optional
        At most this many objects (default: every one that passed).

    Returns
    -------
    list of ObjectCandidate
        The passed ones, best supported first, each with the pixels no better object claimed; empty when none passed.
    """
    if max_objects is not None and (isinstance(max_objects, bool) or int(max_objects) != max_objects or max_objects < 1):
        raise ValueError(f"max_objects: expected a positive integer or None, got {max_objects!r}")
    passed = sorted((c for c in candidates if c.attempt["result"].ok), key=lambda c: -score(c.attempt))
    kept, claimed = [], None
    for c in passed:
        mask = np.asarray(c.mask, dtype=bool)
        if kept and same_object(mask, [k.mask for k in kept]):
            continue
        if claimed is not None:
            mask = mask & ~claimed
        claimed = mask.copy() if claimed is None else claimed | mask
        kept.append(ObjectCandidate(c.segment, c.attempt, mask))
        if max_objects is not None and len(kept) == max_objects:
            break
    return kept


def mask_rle(mask) -> dict:
    """A pixel mask ``(H, W)`` bool as JSON: ``size`` ``[H, W]``, ``counts`` (alternating run lengths over the
    row-major pixels, the first a run of ``False``, possibly 0), ``pixels`` and ``bbox`` ``[u0, v0, u1, v1]``
    (inclusive; ``None`` when empty)."""
    m = np.asarray(mask, dtype=bool)
    if m.ndim != 2:
        raise ValueError(f"mask: expected an (H, W) array, got shape {m.shape}")
    flat = m.ravel()
    change = np.flatnonzero(np.diff(flat.astype(np.int8))) + 1
    edges = np.concatenate([[0], change, [flat.size]])
    counts = np.diff(edges).tolist()
    if flat.size and flat[0]:
        counts = [0] + counts
    return {"size": [int(m.shape[0]), int(m.shape[1])], "counts": [int(c) for c in counts],
            "pixels": int(np.count_nonzero(m)), "bbox": mask_bbox(m), "order": "row-major runs, the first of False"}


def mask_bbox(mask) -> list | None:
    """``[u0, v0, u1, v1]`` (pixels, inclusive) around a mask ``(H, W)`` bool; ``None`` when it is empty."""
    from ...data.images import mask_bounds

    bounds = mask_bounds(mask)
    if bounds is None:
        return None
    v0, v1, u0, u1 = bounds
    return [u0, v0, u1 - 1, v1 - 1]


def rle_mask(record: dict) -> np.ndarray:
    """The ``(H, W)`` bool mask of a :func:`mask_rle` record."""
    try:
        H, W = (int(x) for x in record["size"])
        counts = np.asarray(record["counts"], dtype=np.int64)
    except (KeyError, TypeError, ValueError) as exc:
        raise ValueError(f"mask: expected a record with 'size' [H, W] and 'counts', got {record!r:.80}") from exc
    if counts.sum() != H * W or np.any(counts < 0):
        raise ValueError(f"mask: run lengths sum to {int(counts.sum())}, not {H} x {W} = {H * W} pixels")
    values = np.arange(len(counts)) % 2 == 1
    return np.repeat(values, counts).reshape(H, W)
