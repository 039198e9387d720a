"""``ancsh demo``: the main job of the README, end to end on built-in data.

It grows with the pipeline: today it builds a two-part articulated object, poses it
by forward kinematics and prints the part poses.
"""

from __future__ import annotations


def register(sub) -> None:
    p = sub.add_parser("demo", help="run the full pipeline on built-in data and print a per-part table")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.set_defaults(func=run)


def run(args) -> int:
    import numpy as np
    import trimesh

    from .model import ArticulatedModel, Joint, Part

    rng = np.random.default_rng(args.seed)
    base = trimesh.creation.box((0.3, 0.02, 0.2))
    lid = trimesh.creation.box((0.3, 0.2, 0.01))
    model = ArticulatedModel(
        parts=(Part("base", base), Part("display", lid)),
        joints=(Joint("hinge", "revolute", "base", "display", axis=[1, 0, 0], pivot=[0, 0.01, -0.1], lower=0, upper=2.5, rest=1.57),),
        name="demo_laptop",
    )
    q = model.random_states(rng)
    print(f"{model.name}: joint state {np.degrees(q[0]):.1f} deg")
    for part, T in zip(model.parts, model.forward_kinematics(q)):
        print(f"  {part.name:10s} {T}")
    return 0
