"""Checkpoint without the optimizer state (for the trip back): python strip.py IN OUT."""
import sys

import torch

ck = torch.load(sys.argv[1], map_location="cpu", weights_only=False)
ck.pop("optimizer", None)
torch.save(ck, sys.argv[2])
print(sys.argv[2], ck["step"], round(ck["elapsed_s"]), "s")
