"""Device check: 5 training steps on CUDA against the CPU (ancsh.studies.gpu_check.compare_training)."""
import json
import sys

import torch

from ancsh.studies.gpu_check import LOSS_RTOL_FIRST_STEP, compare_training

dev = torch.device(sys.argv[1] if len(sys.argv) > 1 else "cuda")
print("device", dev, torch.cuda.get_device_name(dev) if dev.type == "cuda" else "cpu", "torch", torch.__version__)
t = compare_training(dev, steps=5)
print(json.dumps(t, default=lambda x: float(x) if hasattr(x, "__float__") else str(x)))
print("first-step loss rel diff", t["loss_rel_diff"][0], "limit", LOSS_RTOL_FIRST_STEP,
      "PASS" if t["loss_rel_diff"][0] <= LOSS_RTOL_FIRST_STEP else "FAIL")
