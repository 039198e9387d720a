"""``python -m ancsh.cli.bench.fit_translation``: the measurements of ``docs/results/fit_translation.md``
(:mod:`ancsh.studies.fit_translation`).

``measure --variant causes|reverse|coupling|sources|stretch --frames N --out R.json`` writes the records; ``tables R.json`` prints the page's
tables; ``anchor --category C --frames N`` measures where the shipped network's NPCS error is smallest; ``evaluate-symmetric ARGS`` runs ``ancsh ARGS`` (e.g. ``evaluate --category laptop ...``) with the previous
default scale estimator of the exact fits (``FitConfig(scale_estimator="symmetric")``), for the page's
before/after rows; ``evaluate-with JSON ARGS`` runs ``ancsh ARGS`` with the ``FitConfig`` fields of ``JSON`` as the
defaults of every fit (e.g. the NPCS biases on the shipped networks' predictions).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import sys


def main(argv=None) -> int:
    from ...studies.fit_translation import VARIANTS

    p = argparse.ArgumentParser(prog="python -m ancsh.cli.bench.fit_translation",
                                description="The fit's translation error by cause (docs/results/fit_translation.md).")
    sub = p.add_subparsers(dest="what", required=True)
    m = sub.add_parser("measure", help="fit the fit benchmark's frames with every method of a variant")
    m.add_argument("--variant", choices=VARIANTS, default="causes")
    m.add_argument("--frames", type=int, default=8, help="test frames per category (default 8)")
    m.add_argument("--categories", default="", help="comma-separated (default: the paper's five)")
    m.add_argument("--out", required=True, help="records JSON")
    t = sub.add_parser("tables", help="the page's markdown tables of a records file")
    t.add_argument("records")
    a = sub.add_parser("anchor", help="where the shipped network's NPCS error is smallest: NPCS origin vs visible centroid")
    a.add_argument("--category", required=True)
    a.add_argument("--frames", type=int, default=40)
    e = sub.add_parser("evaluate-symmetric", help="an ancsh command with the previous default scale estimator")
    e.add_argument("ancsh_args", nargs=argparse.REMAINDER)
    w = sub.add_parser("evaluate-with", help="an ancsh command with other FitConfig defaults (a JSON object)")
    w.add_argument("fit_config", help='FitConfig fields, e.g. \'{"npcs_bias_weight": 0.01}\'')
    w.add_argument("ancsh_args", nargs=argparse.REMAINDER)
    args = p.parse_args(argv)
    if args.what == "measure":
        from ...studies.fit_translation import measure
        from ...studies.report import write_json

        cats = tuple(c for c in args.categories.split(",") if c)
        recs = measure(args.frames, cats, variant=args.variant, progress=lambda line: print(line, flush=True))
        print(f"wrote {write_json(args.out, recs)}")
        return 0
    if args.what == "anchor":
        import numpy as np

        from ...studies.fit_translation import npcs_anchor

        recs = npcs_anchor(args.category, args.frames)
        for part in dict.fromkeys(r["part"] for r in recs):
            sel = [r for r in recs if r["part"] == part]
            o, c = np.array([r["origin"] for r in sel]), np.array([r["centroid"] for r in sel])
            print(f"{args.category} {part}: {len(sel)} frames, |S(origin)| {o.mean():.4f}, |S(centroid) - centroid| "
                  f"{c.mean():.4f}, origin smaller on {np.mean(o < c):.0%}")
        return 0
    if args.what == "tables":
        from ...studies.fit_translation import tables

        with open(args.records) as f:
            print("\n".join(tables(json.load(f))))
        return 0
    if args.what == "evaluate-with":
        from ...solvers.fit import FitConfig
        from .._args import fit_config_fields

        try:
            defaults = fit_config_fields(args.fit_config, "fit_config")
        except ValueError as e:
            p.error(str(e))
        try:
            FitConfig(**defaults)
        except (ValueError, TypeError) as e:  # a bad value; an unknown field
            p.error(f"fit_config: {e}")
        with fit_config_defaults(defaults):
            return _ancsh(args.ancsh_args)
    with fit_config_defaults({"scale_estimator": "symmetric"}):
        return _ancsh(args.ancsh_args)


def _ancsh(ancsh_args: list[str]) -> int:
    from .. import main as ancsh_main

    return ancsh_main(ancsh_args)


@contextlib.contextmanager
def fit_config_defaults(defaults: dict):
    """Within the block ``ancsh.solvers.FitConfig(**kw)`` is ``FitConfig(**{**defaults, **kw})``: the fields of
    ``defaults`` (name -> value) become the defaults of every fit that looks ``FitConfig`` up at call time (the
    ``ancsh`` commands do), and of the shipped networks' fits (``LearnedProvider.fit_config``: its objective, then
    ``defaults``, then the caller's fields); restored after."""
    import ancsh.solvers
    from ...learned.inference.provider import LearnedProvider
    from ...solvers.fit import FitConfig

    learned = LearnedProvider.fit_config
    LearnedProvider.fit_config = lambda self, **kw: learned(self, **{**defaults, **kw})

    class _Defaults:
        paper = staticmethod(FitConfig.paper)
        previous = staticmethod(FitConfig.previous)
        with_objective = staticmethod(FitConfig.with_objective)

        def __new__(cls, **kw):
            return FitConfig(**{**defaults, **kw})

    ancsh.solvers.FitConfig = _Defaults
    try:
        yield
    finally:
        ancsh.solvers.FitConfig = FitConfig
        LearnedProvider.fit_config = learned


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
