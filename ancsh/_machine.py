"""Facts of the machine a report was measured on (for generated reports; standard library only)."""

from __future__ import annotations

import os
import platform

__all__ = ["machine_facts", "describe_machine"]


def machine_facts() -> dict:
    """``{"cpu_count", "machine", "python", "load_average_1min"}`` measured now (load ``None`` where unknown)."""
    try:
        load = round(os.getloadavg()[0], 2)
    except (AttributeError, OSError):
        load = None
    return {
        "cpu_count": os.cpu_count(), "machine": platform.machine(), "python": platform.python_version(),
        "load_average_1min": load,
    }


def describe_machine(facts: dict | None = None) -> str:
    """One phrase for a report, e.g. ``"2 CPU cores (x86_64), 1-min load 3.1 at the start"``."""
    f = machine_facts() if facts is None else facts
    load = "" if f.get("load_average_1min") is None else f", 1-min load {f['load_average_1min']:.1f} at the start"
    return f"{f.get('cpu_count')} CPU cores ({f.get('machine')}){load}"
