"""``ancsh fit-cad`` and ``ancsh evaluate-cad``: CAD-based articulated fitting from the command line.

``ancsh fit-cad --urdf PATH --depth DEPTH --intrinsics K.json [--init INIT.json] [--out R.json] [--png V.png]``
fits a known URDF model to one depth image by articulated ICP:

- ``DEPTH``: ``.npy`` (float depth in the URDF's units, metres for metric models; 0 or NaN =
  no measurement) or ``.png`` (16-bit, multiplied by ``--depth-scale``, default 0.001: millimetres).
- ``K.json``: ``{"fx", "fy", "cx", "cy", "width", "height"}`` (pixels; OpenCV pinhole, pixel
  centres at integer coordinates).
- ``INIT.json`` (optional): ``{"T_cam_base": 4x4 rigid matrix, "q": [absolute joint states]}``;
  ``q`` defaults to the rest state. Without it, :func:`auto_init` tries 8 upright views. The fit is
  :func:`~ancsh.solvers.icp.depth.fit_depth` with :meth:`ArticulatedIcpConfig.instance`: symmetric starts (parts
  swapped, half turns) and the status at the sensor noise (``large_residual``, ``ambiguous``).
- ``--out``: the result as JSON (part poses, joint states, status, their standard deviations:
  ``uncertainty``, see ``docs/json_schema.md``); ``--png``: the fitted
  model drawn over the depth points.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

from ..outputs import write_bytes_atomically
from ._args import check_picture_path, non_negative_int


def register(sub) -> None:
    p = sub.add_parser("fit-cad", help="fit a known URDF model (pose + joint states) to a depth image by articulated ICP")
    p.add_argument("--urdf", required=True, help="URDF of the object (PartNet-Mobility, ReplicaCAD, ...)")
    p.add_argument("--depth", required=True, help="depth image: .npy (float, model units) or 16-bit .png")
    p.add_argument("--intrinsics", required=True, help="JSON with fx, fy, cx, cy, width, height")
    p.add_argument("--init", default=None, help='JSON {"T_cam_base": 4x4, "q": [...]} (default: automatic)')
    p.add_argument("--depth-scale", type=float, default=0.001, help="PNG depth units per model unit (default 0.001)")
    p.add_argument("--max-depth", type=float, default=None, help="ignore depth beyond this (model units)")
    p.add_argument("--points", type=int, default=3000, help="observed points used by ICP (default 3000)")
    p.add_argument("--seed", type=non_negative_int, default=0)
    p.add_argument("--out", default=None, help="write the result as JSON here")
    p.add_argument("--png", default=None, help="draw the fitted model over the depth points here")
    p.add_argument("--urdf-out", type=Path, metavar="DIR", help="write the posed model as a URDF folder (the base in the "
                   "camera frame, the fitted joint states in joint_states.json); a failed fit writes none")
    p.add_argument("--overwrite", action="store_true", help="with --urdf-out: replace the files of an existing folder")
    p.set_defaults(func=run_fit)

    e = sub.add_parser("evaluate-cad", help="AD accuracy of articulated ICP vs rigid ICP on rendered view sequences")
    e.add_argument("--quick", action="store_true", help="a ~2 minute subset")
    e.add_argument("--frames", type=int, default=None, help="views per sequence (default 6, quick 3)")
    e.add_argument("--out", default=None, help="markdown report, a .json is written next to it "
                   "(default: a fresh ancsh_results/evaluate-cad-<time>/cad_fitting.md)")
    e.add_argument("--update-docs", action="store_true", help="write docs/results/cad_fitting.md (when --out is not given)")
    from ._args import add_executor_arguments

    add_executor_arguments(e, workers_default=1, workers_help="worker processes, one object at a time each (default 1: "
                           "in this process); the tables do not depend on it")
    e.set_defaults(func=run_evaluate)


def load_init(path, model):
    """An :class:`ArticulatedPose` from ``{"T_cam_base": 4x4, "q": [...]}`` JSON."""
    import numpy as np

    from ..geometry.transforms import Sim3
    from ..solvers.icp.template import ArticulatedPose

    from ..data.images import read_json

    data = read_json(path, argument="init")
    if not isinstance(data, dict) or "T_cam_base" not in data:
        raise ValueError(f'--init: {path}: expected a JSON object with "T_cam_base" (4x4) and optionally "q"')
    try:
        M = np.asarray(data["T_cam_base"], dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"--init: {path}: T_cam_base must be a 4x4 matrix of numbers") from None
    if M.shape != (4, 4):
        raise ValueError(f"--init: {path}: T_cam_base must be a 4x4 matrix, got shape {M.shape}")
    try:
        T = Sim3.from_matrix(M)
    except ValueError as exc:
        raise ValueError(f"--init: {path}: T_cam_base is not a rigid transform ({exc})") from None
    if not T.is_rigid and abs(T.scale - 1.0) > 1e-6:
        raise ValueError(f"--init: {path}: T_cam_base must be rigid (scale 1), got scale {T.scale:.6g}")
    try:
        q = np.asarray(data.get("q", model.rest_states), dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"--init: {path}: q must be a list of numbers") from None
    if q.shape != (model.num_joints,):
        raise ValueError(f"--init: {path}: q must hold {model.num_joints} joint state(s) (one per joint of the URDF: "
                         f"{[j.name for j in model.joints]}), got shape {q.shape}")
    model.check_states(q, f"--init {path}: q")
    return ArticulatedPose(Sim3(T.rotation, T.translation), q)


def run_fit(args) -> int:
    import numpy as np

    from ..data.images import read_depth, read_intrinsics
    from ..data.urdf import load_urdf
    from ..outputs import provenance
    from ..solvers.icp.depth import depth_points, fit_depth

    if args.png:  # before any work
        check_picture_path(args.png, "--png")
    if args.overwrite and args.urdf_out is None:
        raise ValueError("--overwrite: only with --urdf-out DIR")
    out_dir = args.urdf_out
    if out_dir is not None:
        from ..model.urdf_export import check_urdf_folder

        check_urdf_folder(out_dir, overwrite=args.overwrite, argument="--urdf-out", overwrite_hint="add --overwrite")
    urdf = Path(args.urdf)
    if not urdf.is_file():
        raise FileNotFoundError(f"urdf: no such file {str(urdf)!r}")
    model = load_urdf(urdf)
    if model.num_joints == 0:
        raise ValueError(f"urdf: {urdf.name} has no movable joint (nothing articulated to fit)")
    if args.points < 1:
        raise ValueError(f"--points: expected a positive number of points, got {args.points}")
    intr = read_intrinsics(args.intrinsics)
    depth = read_depth(args.depth, depth_scale=args.depth_scale, shape=(intr.height, intr.width))
    points = depth_points(depth, intr, max_depth=args.max_depth)
    if points.shape[0] < args.points:
        print(f"note: {points.shape[0]} valid pixels, fewer than --points {args.points}: using all of them", file=sys.stderr)
    init = load_init(args.init, model) if args.init else None
    t0 = time.perf_counter()
    result = fit_depth(model, points, points=args.points, rng=args.seed, init=init)
    dt = time.perf_counter() - t0
    q_report = _wrapped_states(model, result.q)
    print(f"{model.name}: {result.status.value} ({result.message}) in {dt:.2f} s, {result.starts} starts, "
          f"{result.iterations} iterations, inliers {100 * result.inlier_ratio:.1f}%, rmse {result.rmse:.4g}")
    sigma = result.uncertainty.joint_state_std if result.uncertainty is not None else np.full(model.num_joints, np.nan)
    for k, j in enumerate(model.joints):
        v, sd = q_report[k], sigma[k]
        print(f"  joint {j.name:24s} {j.type.value:9s} q = {np.degrees(v) if j.is_revolute else v:9.4f}"
              f" +- {np.degrees(sd) if j.is_revolute else sd:.4f} {'deg' if j.is_revolute else 'units'} (1 sigma)")
    for part, T in zip(model.parts, result.T_cam_parts):
        print(f"  part  {part.name:24s} {T}")
    if args.out:
        payload = {**provenance(), "urdf": str(urdf), **result.to_dict()}
        payload["q"] = [float(v) for v in q_report]
        payload["q_rest"] = [float(v) for v in model.rest_states]
        payload["q_relative_to_rest"] = [float(v) for v in q_report - model.rest_states]
        payload["parts"] = model.part_names
        payload["joints"] = [j.name for j in model.joints]
        from ..outputs import json_safe

        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        write_bytes_atomically(Path(args.out), json.dumps(json_safe(payload), indent=1, allow_nan=False).encode())
        print(f"wrote {args.out}")
    if args.png:
        print(f"wrote {draw_fit(model, result, points, intr, args.png)}")
    if out_dir is not None:
        if result.ok:
            from ..model.urdf_export import write_urdf

            path = write_urdf(model, out_dir, states=result.q, T_root_base=result.T_cam_base, overwrite=args.overwrite)
            print(f"wrote {path} (joint states in {out_dir / 'joint_states.json'})")
        else:
            print(f"no URDF written: the fit failed ({result.status.value})")
    return 0 if result.ok else 1


def _wrapped_states(model, q):
    """Absolute joint states with those of unlimited (continuous) revolute joints wrapped into ``(-pi, pi]``."""
    import numpy as np

    q = np.array(q, dtype=np.float64)
    for k, j in enumerate(model.joints):
        if j.is_revolute and not (np.isfinite(j.lower) and np.isfinite(j.upper)):
            q[k] = -((-q[k] + np.pi) % (2 * np.pi) - np.pi)
    return q


def draw_fit(model, result, points_cam, intrinsics, path, *, title: str | None = None) -> Path:
    """Image-plane picture: observed points (grey) and the fitted model's surface per part (colours); returns the
    path written (``.png`` added to a name without a suffix)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    from ..data.render import project
    from ..data.show import save_figure
    from ..model.articulated import sample_surface_with_normals

    fig, ax = plt.subplots(figsize=(6.4, 4.8))
    points_cam = np.asarray(points_cam)
    uv, _ = project(points_cam[points_cam[:, 2] > 0], intrinsics)
    ax.scatter(uv[:, 0], uv[:, 1], s=1, c="0.6", label="observed")
    rng = np.random.default_rng(0)
    for j, (part, T) in enumerate(zip(model.parts, result.T_cam_parts)):
        if part.mesh is None:
            continue
        p, _ = sample_surface_with_normals(part.mesh, 1500, rng)
        pc = T.apply(p)
        uvp, _ = project(pc[pc[:, 2] > 0], intrinsics)
        ax.scatter(uvp[:, 0], uvp[:, 1], s=1, color=f"C{j}", label=part.name)
    ax.set_xlim(0, intrinsics.width)
    ax.set_ylim(intrinsics.height, 0)
    ax.set_aspect("equal")
    ax.legend(loc="upper right", markerscale=6, fontsize=7)
    ax.set_title(title or f"{model.name}: {result.status.value}")
    fig.tight_layout()
    path = save_figure(fig, path, dpi=100)
    plt.close(fig)
    return path


def run_evaluate(args) -> int:
    from dataclasses import replace

    from ._args import executor_from_args
    from ..outputs import report_path
    from ..studies.cad import EvalConfig, run_evaluation, write_report

    executor = executor_from_args(args)
    config = EvalConfig.quick() if args.quick else EvalConfig()
    if args.frames is not None:
        if args.frames < 1:
            raise ValueError(f"--frames: expected a positive number of views, got {args.frames}")
        config = replace(config, frames=int(args.frames))
    command = "ancsh evaluate-cad" + (" --quick" if args.quick else "") + (f" --frames {args.frames}" if args.frames else "")
    command += f" --out {args.out}" if args.out is not None else " --update-docs" if args.update_docs else ""
    command += f" --workers {args.workers}" if args.workers != 1 else ""
    command += f" --executor {args.executor}" if args.executor != "local" else ""
    command += f" --ray-address {args.ray_address}" if args.ray_address else ""
    out = report_path(args.out, update_docs=args.update_docs, docs_name="cad_fitting.md", command="evaluate-cad")
    t0 = time.perf_counter()

    def progress(name, noise, recs):
        art = [r for r in recs if r.method == "articulated_icp"]
        acc = sum(r.chain_correct for r in art) / max(len(art), 1)
        print(f"  {name:45s} noise={'yes' if noise else 'no ':3s} articulated ICP chain AD acc {100 * acc:5.1f}% "
              f"[{time.perf_counter() - t0:6.0f} s]", file=sys.stderr, flush=True)

    records, meta = run_evaluation(config, progress=progress, executor=executor)
    text = write_report(records, meta, out, command=command, wall_s=time.perf_counter() - t0)
    print(text)
    return 0
