"""``ancsh bench fit``: every fitting formulation and the official baseline, side by side.

:mod:`.measure` renders the frames, corrupts their correspondences and fits every method (records);
:mod:`.report` writes ``fit_benchmark.md`` / ``.json`` from them (:mod:`.speed`: its speed section). The command's arguments are in
:mod:`ancsh.cli.bench.fit`."""

from __future__ import annotations

from .measure import (DEFAULT_METHOD, PREVIOUS_METHOD, VERDICT_FRAMES, BenchConfig, BenchFrame, Method, QUICK, FULL,
                      THIN_PARTS, available_methods, evaluate_fit, load_frames, run_benchmark)
from .report import headline, overall, summarize, verdict, verdict_line, write_report

__all__ = ["BenchConfig", "BenchFrame", "DEFAULT_METHOD", "Method", "PREVIOUS_METHOD", "QUICK", "FULL", "THIN_PARTS",
           "VERDICT_FRAMES", "available_methods", "evaluate_fit", "load_frames", "run_benchmark", "headline", "overall",
           "summarize", "verdict", "verdict_line", "write_report"]
