"""Tables of docs/results/levers_gpu.md from the GPU run's histories and the CPU evaluations.

    python docs/results/levers_gpu/report.py EVAL_DIR [EVAL_DIR ...] > tables.md

Each EVAL_DIR is the --out folder of one `ancsh evaluate --category laptop ... --real builtin` of one run's
best.pt (or of the shipped network); the tables are those of docs/results/capacity_gpu/report.py, whose
functions this reuses, with the paired comparison against the run without a lever (``base``).
"""

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "capacity_gpu"))

from report import curves, paired, table1  # noqa: E402  (docs/results/capacity_gpu/report.py)

RUNS = ("base", "normals", "roll30", "pose01", "pose1", "all")

if __name__ == "__main__":
    print("\n".join(curves(RUNS, HERE)))
    print()
    print("\n".join(table1(sys.argv[1:])))
    print()
    print("\n".join(paired(sys.argv[1:], reference="base")))
