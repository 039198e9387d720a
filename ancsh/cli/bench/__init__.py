"""``ancsh bench``: a parser group that other modules extend with benchmarks.

Each entry of :data:`BENCH_MODULES` is ``"module"`` or ``"module:function"``; the function
(default ``register``) receives the ``bench`` sub-parsers and adds one benchmark whose
``func`` default runs it. Modules are imported when the parser is built, so keep their
top level light (heavy imports inside ``func``).
"""

from __future__ import annotations

import importlib

# Modules that contribute ``ancsh bench <name>`` sub-commands, in help order.
BENCH_MODULES = [
    "ancsh.cli.bench.render:register_bench",
    "ancsh.cli.bench.fit",
    "ancsh.cli.bench.fit_profile",
    "ancsh.cli.bench.learned",
    "ancsh.cli.bench.uncertainty",
    "ancsh.cli.bench.refinement",
    "ancsh.cli.bench.train_test_gap",
    "ancsh.cli.bench.gpu_check:register_bench",
    "ancsh.cli.bench.scaling:register_bench",
    "ancsh.cli.bench.tracking",
    "ancsh.cli.bench.track_scenes",
    "ancsh.cli.bench.real_frames",
    "ancsh.cli.bench.twin",
    "ancsh.cli.bench.sensor_realism",
    "ancsh.cli.bench.scenes",
    "ancsh.cli.bench.mask_refusal",
    "ancsh.cli.bench.latency",
    "ancsh.cli.bench.cad_auto",
]


def register(sub) -> None:
    from .. import BENCH_HELP

    p = sub.add_parser("bench", help=BENCH_HELP)
    bench_sub = p.add_subparsers(dest="bench", metavar="BENCHMARK")
    p.set_defaults(func=lambda args: _help(p))
    for entry in BENCH_MODULES:
        module, _, function = entry.partition(":")
        getattr(importlib.import_module(module), function or "register")(bench_sub)


def _help(parser) -> int:
    parser.print_help()
    return 0
