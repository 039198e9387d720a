"""Machine facts of generated reports are measured, not written by hand."""

import os

from ancsh._machine import describe_machine, machine_facts


def test_machine_facts_are_measured_and_described():
    facts = machine_facts()
    assert facts["cpu_count"] == os.cpu_count()
    text = describe_machine(facts)
    assert f"{os.cpu_count()} CPU cores" in text and "2-core" not in text
    assert describe_machine({"cpu_count": 8, "machine": "arm64", "load_average_1min": None}) == "8 CPU cores (arm64)"
