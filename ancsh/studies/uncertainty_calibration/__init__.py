"""``ancsh bench uncertainty``: are the fits' standard deviations calibrated? Measure, inflate, report.

:mod:`.measure` fits rendered frames of each category with each provider and keeps every fitted quantity's error
with its raw covariance; :mod:`.statistics` normalises the errors (squared Mahalanobis distances), measures their
coverage of 68 / 95 % and fits the inflation maps; :mod:`.report` writes ``uncertainty_calibration.md`` / ``.json``,
the reliability plot, and installs the maps (``ancsh/weights/uncertainty_inflation.json``). The command's
arguments are in :mod:`ancsh.cli.bench.uncertainty`."""

from __future__ import annotations

from .measure import CalibrationConfig, merge_records, measure, save_records, load_records, PROVIDERS, DEFAULT_PROVIDERS
from .statistics import (COVERAGE_TARGETS, CORRELATION_GRID, QUANTITIES, ErrorRecord, coverage, error_records,
                         fit_inflation, fit_quantity_inflation, fit_sigma_map, inflated_errors, normalised_errors,
                         raw_sigmas, summarize)
from .report import describe_sigma_map, write_report, install, reliability_plot

__all__ = ["CalibrationConfig", "merge_records", "measure", "save_records", "load_records", "PROVIDERS",
           "DEFAULT_PROVIDERS", "COVERAGE_TARGETS", "CORRELATION_GRID", "QUANTITIES", "ErrorRecord", "coverage",
           "error_records", "fit_inflation", "fit_quantity_inflation", "fit_sigma_map", "inflated_errors",
           "normalised_errors", "raw_sigmas", "summarize", "describe_sigma_map", "write_report", "install",
           "reliability_plot"]
