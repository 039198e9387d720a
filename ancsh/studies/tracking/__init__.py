"""``ancsh bench tracking``: tracking over sequences against independent per-frame fits.

:mod:`.measure` runs the trackers and the per-frame fits over seeded test sequences (records per frame);
:mod:`.statistics` summarises them (errors per method, coverage of the error bars, frame-to-frame correlation);
:mod:`.report` writes ``tracking.md`` / ``.json``. The command's arguments are in :mod:`ancsh.cli.bench.tracking`."""

from __future__ import annotations

from .measure import (BenchConfig, run_benchmark, calibrate, default_urdf, tracked_provider_key, AD_THRESHOLD,
                      COVERAGE_QUANTITIES)
from .statistics import summarize, CORRELATION_KINDS
from .report import write_report

__all__ = ["BenchConfig", "run_benchmark", "calibrate", "default_urdf", "tracked_provider_key", "AD_THRESHOLD",
           "COVERAGE_QUANTITIES", "summarize", "CORRELATION_KINDS", "write_report"]
