"""The point-to-plane term of template fitting (now defined with the other terms in
:mod:`ancsh.solvers.terms`, so the term registry always holds it); kept as an import path."""

from ..terms import PointToPlaneTerm, plane_moments

__all__ = ["PointToPlaneTerm", "plane_moments"]
