"""The ``ancsh`` command line.

Each sub-command lives next to the code it drives, in a module exposing
``register(subparsers)``; that function adds a parser whose ``func`` default
receives the parsed arguments and returns an exit code. Heavy imports happen
inside ``func``, so ``ancsh --help`` stays fast.
"""

from __future__ import annotations

import argparse
import importlib
import re
import sys

from .._version import __version__

# One example per command, shown at the end of its --help.
EXAMPLES = {
    "demo": "ancsh demo --categories laptop,oven --out demo_out",
    "train": "ancsh train --category laptop --data data/laptop_train --time-limit-min 30   # then: --resume; "
             "on 2 processes: torchrun --nproc_per_node 2 -m ancsh train ...",
    "export": "ancsh export --run runs/laptop_ancsh --data data/laptop_train --out ancsh/weights/laptop.pt "
              "--test-data data/laptop_test",
    "predict": "ancsh predict --depth D.png --intrinsics K.json --category laptop --out result.json --png view.png",
    "evaluate": "ancsh evaluate --category laptop --quick            # writes a fresh ancsh_results/evaluate-laptop-<time>/",
    "weights": "ancsh weights --out weights.md",
    "calibrate": "ancsh calibrate --category laptop --frames 800 --update-docs --install   # --object: p_object",
    "data": "ancsh data generate --category laptop --split train --frames 1000 --out data/laptop_train",
    "data generate": "ancsh data generate --category laptop --split train --frames 1000 --out data/laptop_train",
    "data show": "ancsh data show data/laptop_train --frame 7 --out view.png",
    "data import": "ancsh data import ../shared/data/partnet_mobility --out catalog_out",
    "data ranges": "ancsh data ranges --out ranges.md",
    "bench learned-ablation": "ancsh bench learned-ablation --runs base=runs/laptop_ancsh wide=runs/laptop_wide --frames 100",
    "bench roll-equivariance": "ancsh bench roll-equivariance --categories oven laptop --frames 20",
    "bench learned-cost": "ancsh bench learned-cost --variants today new --repeats 6",
    "bench template-refinement": "ancsh bench template-refinement --categories laptop --frames 20 --real-frames 0",
    "bench refine-defaults": "ancsh bench refine-defaults --reports docs/results   # add --install to write them",
    "bench train-test-gap": "ancsh bench train-test-gap --categories laptop --frames 50 --real-frames 0",
    "bench": "ancsh bench fit --quick",
    "bench render": "ancsh bench render --frames 20 --categories laptop",
    "bench scaling": "ancsh bench scaling --out docs/results/scaling.md   # local processes vs Ray, 1 and 2 workers",
    "bench gpu-check": "ancsh bench gpu-check --device cuda   # on a machine with a GPU: CUDA against the CPU",
    "bench fit": "ancsh bench fit --quick               # writes a fresh ancsh_results/bench-fit-<time>/",
    "bench fit-profile": "ancsh bench fit-profile --frames 2 --categories laptop --repeats 1   # one exact fit's "
                         "stages, beside the official scheme",
    "bench uncertainty": "ancsh bench uncertainty --frames 150 --update-docs --install   # ~30 CPU-minutes",
    "fit-cad": "ancsh fit-cad --urdf mobility.urdf --depth D.png --intrinsics K.json --out fit.json --png fit.png",
    "bench cad-auto": "ancsh bench cad-auto --per-category 1 --seeds 0 1   # fit-cad's automatic start: right / "
                      "wrong but success / refused",
    "evaluate-cad": "ancsh evaluate-cad --quick           # --update-docs rewrites docs/results/cad_fitting.md",
    "serve": "ancsh serve --root frames/ --categories laptop   # then: curl -s localhost:8765/health",
    "track": "ancsh track --depth frames/ --intrinsics K.json --category laptop -k 3 --out track.jsonl",
    "bench tracking": "ancsh bench tracking --update-docs   # tracking vs per-frame fitting, docs/results/tracking.md",
    "bench track-scenes": "ancsh bench track-scenes --categories laptop --length 20   # multi-object tracking vs "
                          "per-frame predict, docs/results/track_scenes.md",
    "bench real-frames": "ancsh bench real-frames --update-docs   # ../shared/data/real_frames, docs/results/real_frames.md",
    "bench twin": "ancsh bench twin --categories laptop --frames 2   # exported fit models against the depth",
    "bench sensor-realism": "ancsh bench sensor-realism --frames 5   # real frames' sensor artefacts against renders",
    "bench scenes": "ancsh bench scenes --categories box laptop --frames 5 --stress-frames 4 --seeds 0 1 2   # rendered "
                    "scenes: single objects, then two or three of one category",
    "bench latency": "ancsh bench latency --stress-frames 2 --repeats 2   # warm, cold, stages, serve, workers",
    "category": "ancsh category build examples/categories/single_drawer.toml --urdfs ../shared/data/partnet_mobility "
                "--out categories/single_drawer   # then: ancsh predict --category categories/single_drawer ...",
    "category check": "ancsh category check examples/categories/single_drawer.toml --urdfs ../shared/data/partnet_mobility",
    "category build": "ancsh category build examples/categories/single_drawer.toml --urdfs ../shared/data/partnet_mobility "
                      "--out categories/single_drawer --size notebook",
    "bench mask-refusal": "ancsh bench mask-refusal --categories laptop box --frames 20   # what p_object refuses "
                          "under a mask",
}

# Modules that contribute sub-commands, in help order.
COMMAND_MODULES = [
    "ancsh.cli.demo",
    "ancsh.cli.training",
    "ancsh.cli.learned",
    "ancsh.cli.data",
    "ancsh.cli.bench",
    "ancsh.cli.cad",
    "ancsh.cli.track",
    "ancsh.cli.serve",
    "ancsh.cli.category",
]


#: The help line of ``ancsh bench`` (also where its benchmarks are not registered).
BENCH_HELP = "benchmarks that print throughput / accuracy numbers"


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The ``ancsh`` parser. Given the ``command`` that will run, the benchmarks' parsers (which import their
    studies' settings, a few tenths of a second) are built only for ``bench``."""
    parser = argparse.ArgumentParser(
        prog="ancsh",
        description="Category-level articulated object pose estimation from a single depth image (ANCSH).",
    )
    parser.add_argument("--version", action="version", version=f"ancsh {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMAND_MODULES:
        if name == "ancsh.cli.bench" and command not in (None, "bench"):
            sub.add_parser("bench", help=BENCH_HELP)  # not run: its benchmarks' options are not needed
            continue
        importlib.import_module(name).register(sub)
    _add_examples(sub, "")
    return parser


def _add_examples(subparsers, prefix: str) -> None:
    """Put :data:`EXAMPLES` at the end of every (sub-)command's help."""
    for name, p in subparsers.choices.items():
        key = f"{prefix}{name}"
        if key in EXAMPLES:
            p.epilog = f"example:\n  {EXAMPLES[key]}"
            p.formatter_class = argparse.RawDescriptionHelpFormatter
        for action in p._actions:
            if isinstance(action, argparse._SubParsersAction):
                _add_examples(action, f"{key} ")


#: Options whose value may start with a minus sign (pixel coordinates left of or above the image):
#: ``--pixel -5,-5`` is read as ``--pixel=-5,-5`` (argparse would take ``-5,-5`` for an option).
_SIGNED_VALUE_OPTIONS = ("--pixel", "--box")


def _join_signed_values(argv: list[str]) -> list[str]:
    out, i = [], 0
    while i < len(argv):
        a = argv[i]
        if a in _SIGNED_VALUE_OPTIONS and i + 1 < len(argv) and re.match(r"-[0-9.]", argv[i + 1]):
            out.append(f"{a}={argv[i + 1]}")
            i += 2
            continue
        out.append(a)
        i += 1
    return out


def main(argv: list[str] | None = None) -> int:
    argv = _join_signed_values(list(sys.argv[1:] if argv is None else argv))
    parser = build_parser(next((a for a in argv if not a.startswith("-")), None))
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 0
    try:
        return int(args.func(args) or 0)
    except (ValueError, FileNotFoundError, KeyError) as exc:
        print(f"ancsh {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"ancsh {args.command}: interrupted", file=sys.stderr)
        return 130
    except ConnectionError as exc:  # a Ray cluster that does not answer
        print(f"ancsh {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:  # permission denied, no space left on device, read-only file system, ...
        where = f" {exc.filename}" if exc.filename else ""
        print(f"ancsh {args.command}: error: cannot read or write{where}: {exc.strerror or exc}", file=sys.stderr)
        return 2

