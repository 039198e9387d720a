"""Rotation errors of a washing-machine Table 1 report, grouped by the test instance's loader type.

The type is read from the joint axis in the instance's frame (+y up, +z front): a vertical axis is a
front loader's side hinge, an axis along x a top loader's lid hinged at the back, one along z a lid
hinged at a side (generator version 3). Prints mean and median rotation per part and method.

usage: python docs/results/washing_machine_v3/loader_types.py docs/results/washing_machine.json [more reports]
"""
import json
import sys
from pathlib import Path

import numpy as np

from ancsh.data.procedural import instance_seeds, load_instance

TYPES = ("front", "top", "side")


def loader_types() -> dict[str, str]:
    """``{instance name: 'front' | 'top' | 'side'}`` of the washing machine's test instances."""
    out = {}
    for i in range(len(instance_seeds("washing_machine", "test"))):
        model = load_instance("washing_machine", "test", i)
        axis = np.abs(np.asarray(model.joints[0].axis, float))
        out[model.name] = ("top", "front", "side")[int(np.argmax(axis))]
    return out


def main(paths) -> None:
    kind = loader_types()
    for path in paths:
        per_frame = json.loads(Path(path).read_text())["per_frame"]
        types = np.array([kind[n] for n in per_frame["instance"]])
        print(path, {t: int((types == t).sum()) for t in TYPES}, "frames")
        for method in ("exact_reduced", "template", "network"):
            if method not in per_frame:
                continue
            rot = np.array(per_frame[method]["rot_deg"], float)
            cells = [f"{t}: mean {' / '.join(f'{v:.2f}' for v in np.nanmean(rot[types == t], axis=0))}, "
                     f"median {' / '.join(f'{v:.2f}' for v in np.nanmedian(rot[types == t], axis=0))}" for t in TYPES]
            print(f"  {method:14s}", " | ".join(cells))


if __name__ == "__main__":
    main(sys.argv[1:] or ["docs/results/washing_machine.json"])
