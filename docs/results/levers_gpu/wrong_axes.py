"""The frames whose refined joint axis is the wrong one (> 45 deg off) in the committed Table 1 reports: their
instance, true axis (NAOCS) and true opening angle (the absolute joint state, 0 = closed), and the share of the
report's frames opened no further.

    .venv/bin/python docs/results/levers_gpu/wrong_axes.py [CATEGORY ...]   # default: oven washing_machine laptop

The frames are regenerated as `ancsh evaluate` drew them (the test split, the report's seed, frames 0..N-1); the
instance of each is checked against the report's.
"""

import json
import sys
from pathlib import Path

import numpy as np

from ancsh.data.generate import FrameGenerator, GenerationConfig

RESULTS = Path(__file__).resolve().parents[1]


def wrong_axes(category: str, method: str = "network", threshold_deg: float = 45.0) -> list[str]:
    report = json.loads((RESULTS / f"{category}.json").read_text())
    per_frame, seed = report["per_frame"], report["settings"]["seed"]
    gen = FrameGenerator(GenerationConfig(category=category, split="test", seed=int(seed)))
    frames = [gen.frame(i) for i in range(len(per_frame["instance"]))]
    assert [f.instance for f in frames] == list(per_frame["instance"]), "not the report's frames"
    states = np.array([np.rad2deg(f.joint_states_abs[0]) for f in frames])  # 0 = closed for all three
    out = []
    for i, axis in enumerate(per_frame[method]["axis_deg"]):
        if axis is not None and axis[0] > threshold_deg:
            f = frames[i]
            true_axis = np.round(f.gt.joint_axes_naocs[0], 2).tolist()
            out.append(f"| {category} | {i} | {f.instance} | {axis[0]:.1f} | {true_axis} | {states[i]:.1f} "
                       f"| {np.mean(states <= states[i]):.0%} |")
    return out


if __name__ == "__main__":
    print("| category | frame | instance | refined axis error (°) | true axis (NAOCS) | true opening (°) "
          "| report frames at or below this state |\n" + "|---" * 7 + "|")
    for category in sys.argv[1:] or ("oven", "washing_machine", "laptop"):
        print("\n".join(wrong_axes(category)))
