"""The frames whose refined joint axis is the wrong one (> 45 deg off) in the committed Table 1 reports: their
instance, true axis (NAOCS) and true opening angle (the absolute joint state, 0 = closed), and the share of the
report's frames opened no further; then, per category and stage, how many frames opened at most
``NEAR_CLOSED_DEG`` (the threshold of ``ancsh predict``'s nearly-closed note) and how many opened further had their
axis that far off.

    .venv/bin/python docs/results/levers_gpu/wrong_axes.py [CATEGORY ...]   # default: oven washing_machine laptop

The frames are regenerated as `ancsh evaluate` drew them (the test split, the report's seed, frames 0..N-1); the
instance of each is checked against the report's.
"""

import json
import sys
from pathlib import Path

import numpy as np

from ancsh.data.generate import FrameGenerator, GenerationConfig
from ancsh.learned.inference.predict import NEAR_CLOSED_DEG

RESULTS = Path(__file__).resolve().parents[1]


def report_frames(category: str) -> tuple[dict, list, np.ndarray]:
    """The committed report's per-frame records, its test frames (regenerated) and their openings (the first
    joint's absolute state in degrees, 0 = closed for all three)."""
    report = json.loads((RESULTS / f"{category}.json").read_text())
    per_frame, seed = report["per_frame"], report["settings"]["seed"]
    gen = FrameGenerator(GenerationConfig(category=category, split="test", seed=int(seed)))
    frames = [gen.frame(i) for i in range(len(per_frame["instance"]))]
    assert [f.instance for f in frames] == list(per_frame["instance"]), "not the report's frames"
    return per_frame, frames, np.array([np.rad2deg(f.joint_states_abs[0]) for f in frames])


def axis_errors(per_frame: dict, method: str) -> np.ndarray:
    """The first joint's axis error per frame (degrees; NaN where the fit gave none)."""
    return np.array([np.nan if a is None else a[0] for a in per_frame[method]["axis_deg"]])


def wrong_axes(category: str, method: str = "network", threshold_deg: float = 45.0, loaded=None) -> list[str]:
    per_frame, frames, states = loaded or report_frames(category)
    out = []
    for i, axis in enumerate(axis_errors(per_frame, method)):
        if axis > threshold_deg:
            f = frames[i]
            true_axis = np.round(f.gt.joint_axes_naocs[0], 2).tolist()
            out.append(f"| {category} | {i} | {f.instance} | {axis:.1f} | {true_axis} | {states[i]:.1f} "
                       f"| {np.mean(states <= states[i]):.0%} |")
    return out


def near_closed(category: str, threshold_deg: float = 45.0, loaded=None) -> list[str]:
    """Rows: per stage, wrong-axis frames among those opened <= NEAR_CLOSED_DEG and among the others."""
    per_frame, _, states = loaded or report_frames(category)
    near = np.abs(states) <= NEAR_CLOSED_DEG
    out = []
    for method, stage in (("exact_reduced", "first stage"), ("network", "refined")):
        wrong = axis_errors(per_frame, method) > threshold_deg
        out.append(f"| {category} | {stage} | {np.sum(wrong & near)} of {np.sum(near)} | {np.sum(wrong & ~near)} of "
                   f"{np.sum(~near)} |")
    return out


if __name__ == "__main__":
    categories = sys.argv[1:] or ("oven", "washing_machine", "laptop")
    loaded = {c: report_frames(c) for c in categories}
    print("| category | frame | instance | refined axis error (°) | true axis (NAOCS) | true opening (°) "
          "| report frames at or below this state |\n" + "|---" * 7 + "|")
    for category in categories:
        print("\n".join(wrong_axes(category, loaded=loaded[category])))
    print(f"\n| category | stage | axis > 45° off: opened <= {NEAR_CLOSED_DEG:g}° | opened further |\n" + "|---" * 4 + "|")
    for category in categories:
        print("\n".join(near_closed(category, loaded=loaded[category])))
