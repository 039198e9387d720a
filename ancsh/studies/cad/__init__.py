"""``ancsh evaluate-cad``: articulated ICP vs rigid ICP baselines on rendered view sequences (AD accuracy).

:mod:`.measure` renders each object's orbit sequence and fits every method from the same perturbed starts
(per-frame records); :mod:`.report` writes ``cad_fitting.md`` / ``.json``. The command's arguments are in
:mod:`ancsh.cli.cad`."""

from __future__ import annotations

from .measure import (EvalConfig, FrameRecord, SequenceFrame, PartPoints, METHODS, AD_THRESHOLD, ad_correct,
                      evaluation_objects, perturbed_init, render_sequence, run_evaluation)
from .report import write_report

__all__ = ["EvalConfig", "FrameRecord", "SequenceFrame", "PartPoints", "METHODS", "AD_THRESHOLD", "ad_correct",
           "evaluation_objects", "perturbed_init", "render_sequence", "run_evaluation", "write_report"]
