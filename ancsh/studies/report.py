"""The one writer of the studies' reports: what made a report (command, date, machine) and atomic writes.

Every study writes its markdown, JSON and pictures through :func:`write_text`, :func:`write_json` and
``save_figure`` (:func:`ancsh.data.show.save_figure`): a temporary file and a rename in the target folder, so an
interrupted study leaves the old report or none, never half of one, and a symbolic link at the target is replaced,
not followed. A :class:`Provenance` stamps a report with the command that produced it, the UTC date and the machine
facts measured when it ran (:mod:`ancsh._machine`), so that anyone can re-run it.
"""

from __future__ import annotations

import datetime
import json
from dataclasses import dataclass, field
from pathlib import Path

from .._machine import describe_machine, machine_facts
from ..data.show import save_figure  # (the one figure writer: atomic, format from the suffix)
from ..outputs import write_bytes_atomically

__all__ = ["Provenance", "median_text", "save_figure", "utc_date", "write_json", "write_text"]


def median_text(values, spec: str = ".1f") -> str:
    """The median of the finite ``values`` (``None`` and NaN left out) as a table cell, ``"-"`` when there are none."""
    import numpy as np

    v = [x for x in values if x is not None and np.isfinite(x)]
    return format(float(np.median(v)), spec) if v else "-"


def utc_date() -> str:
    """Now, as reports print it: ``"2026-12-03 13:05 UTC"``."""
    return datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")


@dataclass(frozen=True)
class Provenance:
    """What produced a report: the command line, the UTC date and the machine facts, measured at construction.

    Attributes
    ----------
    command : str
        The command that re-runs the study (as it was typed, with its options).
    date : str
        :func:`utc_date` at construction.
    machine : dict
        :func:`ancsh._machine.machine_facts` at construction (CPU count, architecture, Python, 1-min load).
    """

    command: str
    date: str = field(default_factory=utc_date)
    machine: dict = field(default_factory=machine_facts)

    @property
    def machine_text(self) -> str:
        """One phrase for the report, e.g. ``"2 CPU cores (x86_64), 1-min load 1.0 at the start"``."""
        return describe_machine(self.machine)


def write_text(path, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically, creating its folder; returns the path."""
    path = Path(path)
    write_bytes_atomically(path, text.encode("utf-8"))
    return path


def write_json(path, data, **dumps) -> Path:
    """Write ``json.dumps(data, **dumps)`` plus a newline when indented, atomically; returns the path."""
    text = json.dumps(data, **dumps)
    return write_text(path, text + "\n" if dumps.get("indent") is not None else text)
