"""``ancsh bench learned-cost`` and the network-width study: the network size and the training step against cost and accuracy.

:mod:`.measure` times training steps and forward passes (:func:`timing`, :func:`training_cost`: today's step beside
the new one and its variants, in one process with interleaved repetitions) and runs short equal-step trainings and
the pipeline per width (:func:`accuracy`, :func:`pipeline`); :mod:`.report` writes ``learned_cost.md`` / ``.json``.
The arguments are in :mod:`ancsh.cli.bench.learned`."""

from __future__ import annotations

from .measure import SETTINGS, STEP_VARIANTS, StepVariant, timing, accuracy, pipeline, training_cost
from .report import write_cost_report

__all__ = ["SETTINGS", "STEP_VARIANTS", "StepVariant", "timing", "accuracy", "pipeline", "training_cost",
           "write_cost_report"]
