"""The object list of ``ancsh predict``: every passed candidate once, no pixel in two objects; the mask's JSON code."""

from types import SimpleNamespace

import numpy as np
import pytest

from ancsh.learned.inference.objects import ObjectCandidate, mask_rle, rle_mask, select_objects


def _candidate(segment, ok, score, mask):
    return ObjectCandidate(segment, {"result": SimpleNamespace(ok=ok), "score": score}, mask)


def _box(shape, r0, r1, c0, c1):
    m = np.zeros(shape, dtype=bool)
    m[r0:r1, c0:c1] = True
    return m


def test_every_passed_candidate_is_an_object_once_best_first_and_no_pixel_is_shared():
    shape = (40, 60)
    a = _box(shape, 5, 20, 5, 25)  # object A
    a_again = _box(shape, 5, 22, 5, 25)  # A from another depth of plane removal
    b = _box(shape, 5, 20, 22, 45)  # object B, touching A (3 columns shared)
    failed = _box(shape, 25, 35, 0, 60)
    cands = [_candidate(0, True, 0.6, a), _candidate(1, True, 0.5, a_again), _candidate(2, True, 0.9, b),
             _candidate(3, False, 0.99, failed)]
    objects = select_objects(cands, lambda attempt: attempt["score"])
    assert [o.segment for o in objects] == [2, 0]  # best supported first; A once; the failure is none
    assert not (objects[0].mask & objects[1].mask).any()
    assert objects[0].mask.sum() == b.sum() and objects[1].mask.sum() == a.sum() - 15 * 3  # B keeps what both claim
    assert [o.segment for o in select_objects(cands, lambda attempt: attempt["score"], max_objects=1)] == [2]
    assert select_objects([cands[3]], lambda attempt: attempt["score"]) == []
    with pytest.raises(ValueError, match="max_objects"):
        select_objects(cands, lambda attempt: attempt["score"], max_objects=0)


@pytest.mark.parametrize("seed", range(4))
def test_mask_run_length_code_round_trips(seed):
    rng = np.random.default_rng(seed)
    m = rng.random((17, 23)) < (0.1 + 0.8 * rng.random())
    m[0, 0] = bool(seed % 2)  # both first-pixel cases
    rec = mask_rle(m)
    np.testing.assert_array_equal(rle_mask(rec), m)
    assert rec["pixels"] == m.sum() and rec["size"] == [17, 23]
    v, u = np.nonzero(m)
    assert rec["bbox"] == [u.min(), v.min(), u.max(), v.max()]
    assert mask_rle(np.zeros((3, 4), bool))["bbox"] is None
    with pytest.raises(ValueError, match="run lengths"):
        rle_mask({"size": [3, 4], "counts": [5]})
