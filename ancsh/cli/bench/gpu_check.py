"""``ancsh bench gpu-check`` (or ``python -m ancsh.cli.bench.gpu_check``): the arguments of
:mod:`ancsh.studies.gpu_check`, its printed comparison and its exit code (1 when a check fails)."""

from __future__ import annotations

import argparse
import sys



def run(args: argparse.Namespace) -> int:
    import numpy as np
    import torch

    from ...learned.devices import resolve_device
    from ...studies.gpu_check import (LOSS_RTOL_FIRST_STEP, NPCS_MAX_DIFF, ROTATION_DIFF_MAX_DEG, SEG_AGREEMENT_MIN,
                                      compare_prediction, compare_training)

    device = resolve_device(args.device, argument="--device")
    name = torch.cuda.get_device_name(device) if device.type == "cuda" else "CPU"
    print(f"ancsh GPU check: {device} ({name}) against the CPU; torch {torch.__version__}")
    failures = []
    t = compare_training(device, steps=args.steps)
    print(f"training, {args.steps} steps: loss relative difference per step "
          + " ".join(f"{d:.1e}" for d in t["loss_rel_diff"])
          + f"; weights max difference {t['weights_max_diff']:.2e}; "
          f"s/step cpu {t['cpu_s_per_step']:.3f}, {device.type} {t['device_s_per_step']:.3f}")
    if not t["loss_rel_diff"][0] <= LOSS_RTOL_FIRST_STEP:
        failures.append(f"first-step loss differs by {t['loss_rel_diff'][0]:.1e} > {LOSS_RTOL_FIRST_STEP:.0e}")
    if not all(np.isfinite(t["losses_device"])):
        failures.append("non-finite loss on the device")
    p = compare_prediction(device)
    print(f"prediction ({'laptop'} test frame 0): segmentation agreement {p['seg_agreement']:.4f}, NPCS max difference "
          f"{p['npcs_max_diff']:.1e}, exact_reduced rotation difference {p['fit_rotation_diff_deg']:.3f} deg "
          f"(fits ok: {p['fits_ok']}); network s cpu {p['cpu_network_s']:.3f}, {device.type} {p['device_network_s']:.3f}")
    if not p["seg_agreement"] >= SEG_AGREEMENT_MIN:
        failures.append(f"segmentation agreement {p['seg_agreement']:.4f} < {SEG_AGREEMENT_MIN}")
    if not p["npcs_max_diff"] <= NPCS_MAX_DIFF:
        failures.append(f"NPCS difference {p['npcs_max_diff']:.1e} > {NPCS_MAX_DIFF:.0e}")
    if not p["fit_rotation_diff_deg"] <= ROTATION_DIFF_MAX_DEG:
        failures.append(f"fitted rotations differ by {p['fit_rotation_diff_deg']:.3f} deg > {ROTATION_DIFF_MAX_DEG}")
    print("PASS" if not failures else "FAIL: " + "; ".join(failures))
    return 0 if not failures else 1


def _parser(parser: argparse.ArgumentParser) -> argparse.ArgumentParser:
    parser.add_argument("--device", default="cuda", help="device to check against the CPU (default cuda; cpu = smoke test)")
    parser.add_argument("--steps", type=int, default=5, help="training steps (default 5)")
    parser.set_defaults(func=run)
    return parser


def register_bench(bench_sub) -> None:
    """``ancsh bench gpu-check``."""
    _parser(bench_sub.add_parser("gpu-check", help="train a few steps and predict on a CUDA device and on the CPU; "
                                 "compare (run it on a machine with a GPU)"))


def main(argv=None) -> int:
    args = _parser(argparse.ArgumentParser(prog="python -m ancsh.cli.bench.gpu_check",
                                           description="A short check that the network trains and predicts on a GPU as on the CPU."))
    args = args.parse_args(argv)
    try:
        return run(args)
    except ValueError as exc:
        print(f"gpu_check: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
