"""Find the object in a depth image without a mask: remove supporting planes, segment, rank candidates.

:func:`isolate_object` works on the organised image, subsampled to about
:data:`TARGET_GRID_PIXELS` pixels (a 1280x720 frame every 6th pixel): it removes planes wider than
any object of the category (floors, table tops, stair treads and risers, walls: RANSAC planes whose
connected pieces are wider than the category's largest size times :data:`SIZE_FACTOR`, or wider than
a typical one and running out of the view -- the image's edge or a region without depth joined to it, such as a
sensor's dead band; once a plane is a support, its other pieces that run out of the view are too: a riser's ends
beyond the objects standing in front of it), removes the rounded edges where two supports meet, splits the
rest into connected segments where neighbouring pixels' depths jump (more than a few grid spacings
at that depth) -- each segment also with the smaller ones attached to it across a small depth step (a door ajar),
as a second candidate -- and ranks the segments as candidates:

- with an :class:`ObjectHint`: the segment under the pixel ``(u, v)`` (or the nearest one), or
  with most pixels in the box;
- without one: segments whose size fits the category's ``diagonal_range`` first, nearer the
  image centre and nearer the category's typical size first (:data:`SIZE_PRIOR`; in tenths; within one, more
  pixels first); then the rest, closest in size first.

The result is a pixel mask of the first candidate plus every candidate (:class:`Isolation`:
``labels`` and the ranked ``order``), so that a caller who can judge a candidate (the category's
network and fit, :func:`ancsh.learned.inference.predict.predict_depth`) may verify several and
choose, and, when it rejects every one, join two that touch into one more candidate (:func:`merged_candidate`: an
object that plane removal cut in two). A mask given by the user always wins over this (``ancsh predict --mask``).

Far from the camera a sensor's noise outgrows a plane's tolerance: where the noise measured in the image at a pixel's
depth does, planes are searched on points averaged over their surface's neighbours, within that noise
(:mod:`.noise`; without it, objects 4-5 m away came back as one segment with the floor).

Modules: :mod:`.proposals` (:func:`isolate_object`, :class:`Isolation`: the grid, segments and ranking), :mod:`.planes`
(support planes), :mod:`.noise` (the noise and the smoothed points planes are searched on), :mod:`.hints` (:class:`ObjectHint`), :mod:`.verification` (the checks and joins a verifier applies to
the candidates) and :mod:`.grid` (shared helpers and the category's size range); the names below are importable from
here.
"""

from .grid import SAME_SEGMENT_IOU, SIZE_FACTOR  # noqa: F401
from .hints import ObjectHint, parse_hint
from .planes import MAX_PLANES, RANSAC_ITERATIONS, RANSAC_POINTS  # noqa: F401
from .proposals import TARGET_GRID_PIXELS, Cluster, Isolation, isolate_object  # noqa: F401
from .verification import OUT_OF_VIEW_SHARE, behind_surroundings, merged_candidate, out_of_view  # noqa: F401

__all__ = ["ObjectHint", "Cluster", "Isolation", "behind_surroundings", "isolate_object", "merged_candidate", "out_of_view",
           "parse_hint"]
