"""``ancsh evaluate``: the paper's Table 1 / Table 2 and the occlusion analysis on held-out instances.

:mod:`.measure` runs the shipped networks and every fitting method over rendered held-out frames (per-frame
records), :mod:`.statistics` summarises them (means / medians, occlusion bins), :mod:`.report` writes
``<category>.md`` / ``.json``, the occlusion plot and ``<category>_real.md``. The command's arguments are in
:mod:`ancsh.cli.learned`."""

from __future__ import annotations

from ...learned.network.weights import missing_weights_error, shipped_categories
from ...outputs import json_safe
from .measure import (DEFAULT_METHODS, METHODS, PAPER_TABLE1, PAPER_TABLE2, Method, TIMING_KEYS, evaluate_category,
                      fit_method, fit_naocs, naocs_correspondences, npcs_error_budget, per_point_naocs)
from .measure import JOINT_METRICS, PART_METRICS
from .statistics import OCCLUSION_EDGES, occlusion_bins, summarize
from .report import write_json, write_real_report, write_report

__all__ = ["DEFAULT_METHODS", "METHODS", "PAPER_TABLE1", "PAPER_TABLE2", "Method", "TIMING_KEYS", "evaluate_category",
           "fit_method", "fit_naocs", "naocs_correspondences", "npcs_error_budget", "per_point_naocs", "summarize",
           "JOINT_METRICS", "PART_METRICS", "OCCLUSION_EDGES", "occlusion_bins",
           "write_json", "write_real_report", "write_report",
           "json_safe", "missing_weights_error", "shipped_categories"]  # (the last three: their old place)
