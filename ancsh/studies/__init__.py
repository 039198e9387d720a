"""The project's studies: benchmarks, evaluations and calibrations that write the reports of ``docs/results/``.

A study measures with the library (``geometry`` ... ``tracking``) and writes markdown / JSON reports; the library
never imports a study. The ``ancsh bench``, ``ancsh evaluate``, ``ancsh evaluate-cad`` and ``ancsh calibrate``
commands (:mod:`ancsh.cli`) parse the arguments and call them.
"""
