"""ancsh evaluate with the previous default scale estimator (symmetric) for exact fits (docs/results/fit_translation.md)."""
import sys
import ancsh.studies.table1 as ev
from ancsh.solvers.fit import FitConfig

class _Sym:
    paper = staticmethod(FitConfig.paper)
    def __new__(cls, **kw):
        kw.setdefault("scale_estimator", "symmetric")
        return FitConfig(**kw)

import ancsh.solvers
ancsh.solvers.FitConfig = _Sym
from ancsh.cli import main
sys.exit(main(sys.argv[1:]))
