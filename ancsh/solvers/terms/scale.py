"""The common object scale of all parts, soft (:class:`CommonScaleTerm`) or exact (:class:`ExactCommonScaleTerm`)."""

from __future__ import annotations

import casadi as ca

from ..inputs import KinematicStructure, ProgramInputs
from .context import Context, EnergyTerm, register_term


@register_term
class CommonScaleTerm(EnergyTerm):
    """Soft common object scale: ``sqrt(w) (s_j / Gs_j - s_root / Gs_root) / L`` for ``j != root``."""

    name = "common_scale"

    def expression(self, ctx: Context) -> ca.SX:
        return ca.sqrt(ctx.params.get("common_scale_weight")) * _object_scale_differences(ctx)

    def fill(self, structure: KinematicStructure, inputs: ProgramInputs) -> dict:
        return {"common_scale_weight": inputs.require("weights", self.name).common_scale_weight}


@register_term
class ExactCommonScaleTerm(EnergyTerm):
    """One object scale, exactly: ``(s_j / Gs_j - s_root / Gs_root) / L == 0`` for ``j != root``."""

    name = "exact_common_scale"
    kind = "equality"

    def expression(self, ctx: Context) -> ca.SX:
        return _object_scale_differences(ctx)


def _object_scale_differences(ctx: Context) -> ca.SX:
    """``(s_j / Gs_j - s_root / Gs_root) / L`` for every part ``j != root``."""
    r = ctx.structure.root
    out = [(ctx.object_scale(j) - ctx.object_scale(r)) / ctx.L for j in range(ctx.structure.num_parts) if j != r]
    return ca.vertcat(*out) if out else ca.SX(0, 1)
