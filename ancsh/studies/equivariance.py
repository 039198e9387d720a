"""How far a network's fitted rotation follows a camera roll: a measure of its reliance on the camera frame.

A camera rotating about its own centre sees the same surface; rolling it about the ray through the
object's centroid by ``θ`` turns the observed points by ``θ`` about that ray, so the true part
rotations turn by exactly ``θ`` too. A network that reads the object's orientation from its shape
makes the fitted rotations follow (gain 1); one that leans on the camera frame (the object's usual
orientation in the training views) follows only partly (gain < 1), and on test views it is biased
toward that usual orientation. :func:`roll_gain` measures the gain on held-out test frames: per
frame, the ``exact_reduced`` fit of the rendered points and of the same points rolled by ``±θ``
(alternating), and the component of the difference rotation along the roll axis over ``θ``.
``ancsh bench roll-equivariance`` (:func:`roll_equivariance`, :func:`write_roll_report`) compares several networks.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from .report import utc_date, write_text

__all__ = ["measure_roll_gain", "roll_equivariance", "roll_gain", "roll_points", "write_roll_report"]


def roll_points(points_cam: np.ndarray, angle_rad: float) -> tuple[np.ndarray, np.ndarray]:
    """Roll the camera by ``angle_rad`` about the ray through the points' centroid.

    Parameters
    ----------
    points_cam : (N, 3) float64
        Camera frame, metres.
    angle_rad : float

    Returns
    -------
    rolled : (N, 3) float64
        The points seen by the rolled camera (turned about the ray by ``angle_rad``).
    axis : (3,) float64
        The unit roll axis (camera frame).
    """
    from scipy.spatial.transform import Rotation

    p = np.asarray(points_cam, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 3 or len(p) == 0 or not np.all(np.isfinite(p)):
        raise ValueError(f"points_cam: expected finite (N, 3) points, got shape {p.shape}")
    c = p.mean(axis=0)
    if np.linalg.norm(c) < 1e-9:
        raise ValueError("points_cam: centroid at the camera centre; the roll axis is undefined")
    axis = c / np.linalg.norm(c)
    R = Rotation.from_rotvec(angle_rad * axis).as_matrix()
    return p @ R.T, axis  # a rotation about the camera centre: the ray through the centroid is kept


def roll_gain(category: str, weights=None, *, frames: int = 30, angle_deg: float = 10.0, seed: int = 0,
              oracle: bool = False) -> dict:
    """Measure the roll gain of a network on ``frames`` rendered test frames of ``category``.

    Parameters
    ----------
    category : str
        Procedural category (its held-out test instances are rendered, seed ``seed``).
    weights : str or path, optional
        Weights file or checkpoint (default: the shipped network of ``category``).
    frames : int
    angle_deg : float
        Roll angle (degrees, in ``(0, 45]``), applied as ``+angle`` and ``-angle`` on alternate frames.
    oracle : bool
        Measure the ground-truth correspondences instead of a network (the reference: gain 1).

    Returns
    -------
    dict
        ``gain`` (frames, parts): per frame and part, the fitted rotation's turn about the roll axis
        over the roll (1 = follows the camera exactly); ``gain_mean``, ``gain_median`` and
        ``gain_sem`` (standard error of the mean) over frames (each the mean over its parts);
        ``frames`` used (frames whose fits both succeeded), ``skipped``, ``weights``,
        ``weights_sha256`` and the settings.
    """
    from ..data.generate import FrameGenerator, GenerationConfig
    from ..learned.inference.provider import LearnedProvider
    from ..solvers.providers.oracle import OracleProvider

    if not 0 < float(angle_deg) <= 45:
        raise ValueError(f"angle_deg: expected a roll in (0, 45] degrees, got {angle_deg!r}")
    if int(frames) < 1:
        raise ValueError(f"frames: expected at least 1, got {frames!r}")
    generator = FrameGenerator(GenerationConfig(category=category, split="test", seed=int(seed)))
    if oracle:
        source, sha, provider_of = "ground truth", None, lambda frame: OracleProvider(frame, "none")
    else:
        provider = LearnedProvider(category if weights is None else str(weights), seed=seed, num_threads=1)
        source, sha, provider_of = provider.network.source, provider.network.sha256, lambda frame: provider
    out = measure_roll_gain((generator.frame(i) for i in range(int(frames))), provider_of,
                            angle_rad=np.radians(float(angle_deg)), seed=int(seed))
    return {"category": category, "weights": source, "weights_sha256": sha, "angle_deg": float(angle_deg),
            "seed": int(seed), **out}


def measure_roll_gain(frames, provider_of, *, angle_rad: float, seed: int = 0) -> dict:
    """The roll gain over ``frames`` (objects with ``.points``), the correspondences of frame ``f`` from
    ``provider_of(f).correspond(observation)``; see :func:`roll_gain` (its ``gain*``, ``frames``, ``skipped``)."""
    from scipy.spatial.transform import Rotation

    from ..solvers.types import Observation
    from ..solvers.formulations import provider_fit_config
    from .table1 import fit_method

    gains, skipped = [], 0
    for i, fr in enumerate(frames):
        angle = angle_rad * (1 if i % 2 == 0 else -1)
        rolled, axis = roll_points(fr.points, angle)
        provider = provider_of(fr)
        fits = []
        for pts in (fr.points, rolled):
            obs = Observation(pts)
            fits.append(fit_method("exact_reduced", obs, provider.correspond(obs), rng=seed + i,
                                   config=provider_fit_config(provider)))
        if not all(f.ok for f in fits):
            skipped += 1
            continue
        row = []
        for a, b in zip(fits[0].T_cam_npcs, fits[1].T_cam_npcs):
            turn = Rotation.from_matrix(b.rotation @ a.rotation.T).as_rotvec()
            row.append(float(turn @ axis) / angle)
        gains.append(row)
    g = np.array(gains, dtype=np.float64).reshape(len(gains), -1)
    per_frame = g.mean(axis=1) if len(g) else np.array([])
    return {
        "frames": len(gains), "skipped": skipped, "gain": g.tolist(),
        "gain_mean": float(per_frame.mean()) if len(per_frame) else float("nan"),
        "gain_median": float(np.median(per_frame)) if len(per_frame) else float("nan"),
        "gain_sem": float(per_frame.std(ddof=1) / np.sqrt(len(per_frame))) if len(per_frame) > 1 else float("nan"),
    }


def roll_equivariance(networks: dict, *, frames: int = 30, angle_deg: float = 10.0, seed: int = 0) -> dict:
    """:func:`ancsh.studies.equivariance.roll_gain` of several networks on the same test frames.

    ``networks``: label -> ``(category, weights or None)`` (``None``: the shipped network of the category).
    """
    rows = {}
    for label, (category, weights) in networks.items():
        rows[label] = roll_gain(category, weights, frames=frames, angle_deg=angle_deg, seed=seed)
        print(f"{label}: gain {rows[label]['gain_mean']:.2f} ± {rows[label]['gain_sem']:.2f}", flush=True)
    for category in dict.fromkeys(c for c, _ in networks.values()):  # the measurement's reference: gain 1
        rows[f"{category}: ground truth"] = roll_gain(category, frames=frames, angle_deg=angle_deg, seed=seed, oracle=True)
    return {"rows": rows, "frames": frames, "angle_deg": angle_deg, "seed": seed}


def write_roll_report(result: dict, path, *, command: str) -> Path:
    """Write :func:`roll_equivariance` output as Markdown to ``path`` (JSON beside it)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    date = utc_date()
    lines = [
        "# Camera-roll equivariance of the networks", "",
        f"Command: `{command}`  ",
        f"Date: {date}; {result['frames']} rendered test frames per network (held-out instances, seed {result['seed']}), "
        f"each fitted (`exact_reduced`) as rendered and after a camera roll of ±{result['angle_deg']:g}° about the ray "
        "through the points' centroid (alternating sign).", "",
        "A camera roll turns the true part rotations by exactly the roll, so the fitted rotations of a network that reads "
        "the orientation from the object's shape follow it (gain 1). A gain below 1 is the share the network follows: "
        "the rest it takes from the camera frame (the object's usual orientation in the training views), and on test "
        "views it is biased toward that usual orientation (`ancsh.studies.equivariance`). Gain: the fitted rotation's "
        "turn about the roll axis over the roll, averaged over parts, then over frames (± its standard error). The "
        "*ground truth* rows fit the true correspondences of the same frames: the measurement's reference.", "",
        "| network | category | weights (sha256) | frames (skipped) | gain mean ± s.e. | median |",
        "|---|---|---|---|---|---|",
    ]
    for label, r in result["rows"].items():
        lines.append(f"| {label} | {r['category']} | `{Path(r['weights']).name}` ({(r['weights_sha256'] or '-')[:12]}) "
                     f"| {r['frames']} ({r['skipped']}) | {r['gain_mean']:.2f} ± {r['gain_sem']:.2f} | "
                     f"{r['gain_median']:.2f} |")
    write_text(path, "\n".join(lines) + "\n")
    write_text(path.with_suffix(".json"), json.dumps(result, indent=1) + "\n")
    return path
