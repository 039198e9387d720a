"""``ancsh bench sensor-realism``: what real depth frames show that the project's renders do not (issue 31, item 5).

:func:`depth_artefacts` measures, on one depth image, the artefacts a depth sensor leaves:

- **missing inside**: the share of pixels without a measurement, not counting holes that touch the image border
  (out of range, sky, the background beyond a rendered floor);
- **holes in blobs**: the share of those missing pixels that lie in connected holes of more than :data:`BLOB_PIXELS`
  pixels (dark, shiny or shadowed surfaces) rather than scattered;
- **dark missing**: with a colour image, the share of dark pixels (mean RGB below :data:`DARK`) without a measurement;
- **at depth jumps**: along rows and columns, every pixel whose neighbours :data:`SPAN` pixels to each side are both
  measured and differ by more than :data:`JUMP_M`, while each side is flat (its next :data:`SPAN` pixels outwards
  within a quarter of the jump: a discontinuity, not a steep slope): the share of those pixels that are missing
  (**dropped**) and the share that lie between both surfaces, more than :data:`BETWEEN_M` from each (**mixed**,
  "flying" pixels);
- **step**: the median gap between consecutive distinct depths within 5 cm of the image's median depth (mm): the
  sensor's quantisation (0 for a continuous depth).

:func:`measure_sensor_realism` measures every real frame (the whole image: scene and objects) and rendered scenes of
the project's categories: a test instance on a floor (so that its outline is a jump against a measured surface, as in
a real scene) with the dataset noise (:class:`~ancsh.data.noise.DepthNoise`, Kinect-like) and with
:meth:`DepthNoise.real_frames` (the edges and steps measured here), side by side.
"""

from __future__ import annotations

import numpy as np

from .report import Provenance, write_json, write_text

__all__ = ["BETWEEN_M", "BLOB_PIXELS", "DARK", "JUMP_M", "SPAN", "depth_artefacts", "floor_scene",
           "measure_sensor_realism", "write_sensor_report"]

#: A depth jump: neighbours SPAN pixels to each side of a pixel differ by more than this (metres).
JUMP_M = 0.05
SPAN = 2
#: A pixel at a jump is "mixed" when it lies more than this (metres) from both sides' depths.
BETWEEN_M = 0.01
#: Missing pixels in connected holes larger than this count as blobs.
BLOB_PIXELS = 100
#: Dark pixels: mean RGB (0..1) below this.
DARK = 0.15
NOISE_MODELS = ("dataset", "real_frames")


def depth_artefacts(depth, rgb=None) -> dict:
    """The artefact measures of one depth image (module docstring).

    Parameters
    ----------
    depth : (H, W) float
        Metres, 0 = no measurement.
    rgb : (H, W, 3) uint8, optional
        The registered colour image (for ``dark_missing``).

    Returns
    -------
    dict
        ``missing_inside``, ``holes_in_blobs`` (NaN without such holes), ``dark_missing`` (NaN without colour or dark
        pixels), ``jump_pixels``, ``dropped``, ``mixed`` (NaN without jumps), ``step_mm``, ``median_depth_m``.
    """
    from scipy.ndimage import label

    d = np.asarray(depth, dtype=np.float64)
    if d.ndim != 2:
        raise ValueError(f"depth: expected an (H, W) image, got shape {d.shape}")
    valid = d > 0
    if not valid.any():
        raise ValueError("depth: no pixel has a measurement")
    missing = ~valid
    labels, n = label(missing)
    sizes = np.bincount(labels.ravel(), minlength=n + 1)
    outside = np.unique(np.concatenate([labels[0], labels[-1], labels[:, 0], labels[:, -1]]))
    sizes[outside] = 0  # holes that touch the border (and label 0, the measured pixels)
    inside = int(sizes.sum())
    missing_inside = inside / (d.size - (np.count_nonzero(missing) - inside))
    holes_in_blobs = float(sizes[sizes > BLOB_PIXELS].sum() / inside) if inside else float("nan")
    dark_missing = float("nan")
    if rgb is not None:
        c = np.asarray(rgb)
        if c.shape[:2] != d.shape:
            raise ValueError(f"rgb: expected the depth's size {d.shape}, got {c.shape[:2]}")
        dark = c[..., :3].astype(np.float64).mean(axis=2) / 255.0 < DARK
        dark_missing = float(missing[dark].mean()) if dark.any() else float("nan")
    jumps = dropped = mixed = 0
    k = SPAN
    for img in (d, d.T):  # rows, then columns: outer a2, side a, middle m, side b, outer b2
        a2, a, m, b, b2 = (img[:, i * k: img.shape[1] - (4 - i) * k] for i in range(5))
        step = np.abs(a - b)
        at = ((a > 0) & (b > 0) & (a2 > 0) & (b2 > 0) & (step > JUMP_M)
              & (np.abs(a2 - a) < 0.25 * step) & (np.abs(b2 - b) < 0.25 * step))
        lo, hi = np.minimum(a, b), np.maximum(a, b)
        jumps += int(at.sum())
        dropped += int((at & (m == 0)).sum())
        mixed += int((at & (m > lo + BETWEEN_M) & (m < hi - BETWEEN_M)).sum())
    z = d[valid]
    z0 = z[np.argmin(np.abs(z - np.median(z)))]  # a measured depth (the median may fall between two surfaces)
    near = np.unique(d[valid & (np.abs(d - z0) < 0.05)])
    step = float(1e3 * np.median(np.diff(near))) if near.size > 1 else float("nan")
    return {"missing_inside": float(missing_inside), "holes_in_blobs": holes_in_blobs, "dark_missing": dark_missing,
            "jump_pixels": jumps, "dropped": dropped / jumps if jumps else float("nan"),
            "mixed": mixed / jumps if jumps else float("nan"), "step_mm": step, "median_depth_m": float(np.median(z))}


def floor_scene(gen, index: int):
    """The noise-free depth ``(H, W)`` of test frame ``index`` of ``gen`` with a floor under the object (a plane
    through its lowest point, +y up in the canonical frame), and the frame."""
    import trimesh

    from ..data.conventions import part_vertices_canonical
    from ..data.render import ModelRenderer
    from ..geometry.transforms import Sim3
    from ..model.articulated import ArticulatedModel, Part

    frame = gen.frame(index)
    model, renderer = gen.instance(frame.instance_index)
    verts = np.concatenate(part_vertices_canonical(model, frame.joint_states_abs))
    lo, hi = verts.min(axis=0), verts.max(axis=0)
    floor = trimesh.creation.box((4.0, 0.02, 4.0))
    floor.apply_translation([(lo[0] + hi[0]) / 2, lo[1] - 0.01, (lo[2] + hi[2]) / 2])
    floor.apply_transform(np.block([[model.R_canon_base.T, np.zeros((3, 1))], [np.zeros((1, 3)), np.ones((1, 1))]]))
    plane = ArticulatedModel((Part("floor", floor),), (), name="floor")
    obj = renderer.render(frame.joint_states_abs, frame.T_cam_base, frame.intrinsics).depth
    ground = ModelRenderer(plane).render(np.zeros(0), frame.T_cam_base @ Sim3(), frame.intrinsics).depth
    stack = np.stack([np.where(obj > 0, obj, np.inf), np.where(ground > 0, ground, np.inf)])
    depth = stack.min(axis=0)
    return np.where(np.isfinite(depth), depth, 0.0), frame


def measure_sensor_realism(folders, *, categories=("box", "laptop"), frames: int = 20, seed: int = 0,
                           progress=None) -> dict:
    """Rows of :func:`depth_artefacts`: each real frame, and per category the mean over ``frames`` rendered floor
    scenes under each noise model of :data:`NOISE_MODELS` (jump shares pooled over the frames' jump pixels)."""
    from ..data.generate import FrameGenerator, GenerationConfig
    from ..data.noise import DepthNoise, apply_noise
    from ..data.real_frames import load_real_frame

    if isinstance(frames, bool) or int(frames) != frames or frames < 1:
        raise ValueError(f"frames: expected a positive integer, got {frames!r}")
    rows = []
    for folder in folders:
        fr = load_real_frame(folder)
        rows.append({"source": "real", "name": fr.name, "frames": 1, **depth_artefacts(fr.depth, fr.rgb)})
        if progress:
            progress(f"real frame {fr.name}")
    models = {"dataset": DepthNoise(), "real_frames": DepthNoise.real_frames()}
    for cat in categories:
        gen = FrameGenerator(GenerationConfig(category=cat, split="test", seed=int(seed)))
        clean = [floor_scene(gen, i)[0] for i in range(int(frames))]
        for name in NOISE_MODELS:
            rng = np.random.default_rng([int(seed), len(name)])
            recs = [depth_artefacts(apply_noise(c, models[name], rng)) for c in clean]
            jumps = sum(r["jump_pixels"] for r in recs)
            row = {"source": f"rendered ({name} noise)", "name": cat, "frames": int(frames), "jump_pixels": jumps}
            for key in ("missing_inside", "holes_in_blobs", "dark_missing", "step_mm", "median_depth_m"):
                vals = np.array([r[key] for r in recs], dtype=np.float64)
                row[key] = float(np.nanmean(vals)) if np.isfinite(vals).any() else float("nan")
            for key in ("dropped", "mixed"):
                row[key] = (float(sum(r[key] * r["jump_pixels"] for r in recs if r["jump_pixels"]) / jumps)
                            if jumps else float("nan"))
            rows.append(row)
        if progress:
            progress(f"rendered {cat}: {frames} frames")
    return {"rows": rows, "settings": {"categories": list(categories), "frames": int(frames), "seed": int(seed),
                                       "noise": {k: v.to_json() for k, v in models.items()}}}


def write_sensor_report(results: dict, path, *, command: str):
    """The markdown table and a JSON of the rows beside it."""
    from pathlib import Path

    path = Path(path)
    prov = Provenance(command)

    def f(x, fmt):
        return "-" if x is None or not np.isfinite(x) else format(x, fmt)

    md = [
        "# Real depth frames against the project's renders: sensor artefacts",
        "",
        f"Command: `{command}`  ",
        f"Date: {prov.date}; machine: {prov.machine_text}  ",
        "Study: `ancsh.studies.sensor_realism`",
        "",
        "Each real frame measured whole (scene and objects); rendered: test instances of each category on a floor "
        f"({results['settings']['frames']} frames each), noise-free depth with the dataset's noise model "
        "(`DepthNoise()`, Kinect-like: half the pixels at depth jumps dropped, Gaussian axial noise) and with "
        "`DepthNoise.real_frames()` (the same with the whole-millimetre steps and the blob holes these frames show: 1 % "
        "of the pixels dropped in blobs). Missing inside: share of pixels without "
        "a measurement, holes touching the image border left out. Holes in "
        f"blobs: share of those in holes of more than {BLOB_PIXELS} pixels. Dark missing: missing share "
        f"of the pixels darker than {DARK} (colour frames only). At depth jumps (neighbours {SPAN} pixels to each side "
        f"measured and more than {100 * JUMP_M:.0f} cm apart, each side flat): dropped = missing, mixed = between both surfaces, more "
        f"than {100 * BETWEEN_M:.0f} cm from each. Step: median gap between distinct depths near the median depth.",
        "",
        "| source | frame / category | frames | median depth (m) | missing inside | holes in blobs | dark missing | "
        "jump pixels | dropped at jumps | mixed at jumps | step (mm) |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in results["rows"]:
        md.append(f"| {r['source']} | {r['name']} | {r['frames']} | {f(r['median_depth_m'], '.2f')} | "
                  f"{f(r['missing_inside'], '.3f')} | {f(r['holes_in_blobs'], '.2f')} | {f(r['dark_missing'], '.2f')} | "
                  f"{r['jump_pixels']} | {f(r['dropped'], '.2f')} | {f(r['mixed'], '.2f')} | {f(r['step_mm'], '.3f')} |")
    write_text(path, "\n".join(md) + "\n")
    write_json(path.with_suffix(".json"), {"command": command, "date": prov.date, "machine": prov.machine, **results})
    return path
