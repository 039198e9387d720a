"""Priors: on the canonical-parameter offsets, on the per-part NPCS biases, and toward a previous frame's solution."""

from __future__ import annotations

import casadi as ca
import numpy as np

from ..inputs import KinematicStructure, ProgramInputs
from .context import Context, EnergyTerm, joint_state_expr, register_term


@register_term
class CanonicalPriorTerm(EnergyTerm):
    """Prior on the canonical-parameter offsets: ``sqrt(w) [dGt_j; dq_k]`` (NAOCS units).

    Only meaningful in a program whose canonical parameters are free (see :class:`Canonical`);
    parameter ``naocs_prior_weight`` (``w``).
    """

    name = "naocs_prior"

    def expression(self, ctx: Context) -> ca.SX:
        if not ctx.canonical.free:
            raise ValueError("naocs_prior: the program's canonical parameters are fixed (free_canonical=False)")
        return ca.sqrt(ctx.params.get("naocs_prior_weight")) * ctx.canonical.offsets()

    def fill(self, structure: KinematicStructure, inputs: ProgramInputs) -> dict:
        return {"naocs_prior_weight": inputs.require("weights", self.name).naocs_prior_weight}


@register_term
class NpcsBiasPriorTerm(EnergyTerm):
    """Prior on per-part NPCS orientation biases: ``sqrt(w) b_j`` (radians), parameter ``npcs_bias_weight`` (``w``).

    A provider's NPCS of one part can be off by a rotation about the NPCS origin common to all its points
    (a per-part orientation error: it does not average out over the points, and a per-part similarity fit
    absorbs it into the part's rotation and keeps the NPCS origin in place). With NPCS biases the data terms
    compare the points with ``s_j R_j exp(b_j) c + t_j`` (:meth:`Context.data_pose`): ``b_j`` takes up
    what the part's data want beyond the joints, at the cost ``w |b_j|^2``, while ``R_j`` (reported)
    keeps the joints exact. With scale biases (``ProgramKey.npcs_scale_bias``) each part's log-scale ``beta_j``
    about its NPCS origin joins ``b_j`` under the same prior (an isotropic NPCS error, which a per-part similarity
    also absorbs; the point-to-point data term then weighs the part by ``exp(-beta_j)``, :meth:`Context.data_weight`),
    with stretch biases (``ProgramKey.npcs_stretch_bias``) also a symmetric traceless stretch ``S_j`` (five parameters),
    so the part's NPCS may be off by any linear map near the identity about its origin, as a per-part affine fit allows.
    Only meaningful in a program with NPCS-bias variables (``ProgramKey.npcs_bias``).
    """

    name = "npcs_bias_prior"

    def expression(self, ctx: Context) -> ca.SX:
        if ctx.npcs_bias is None:
            raise ValueError("npcs_bias_prior: the program has no NPCS-bias variables (npcs_bias=False)")
        return ca.sqrt(ctx.params.get("npcs_bias_weight")) * ca.vertcat(*ctx.npcs_bias)

    def fill(self, structure: KinematicStructure, inputs: ProgramInputs) -> dict:
        return {"npcs_bias_weight": inputs.require("weights", self.name).npcs_bias_weight}


@register_term
class TemporalPriorTerm(EnergyTerm):
    """Prior toward a prediction from previous frames (tracking): ``[sqrt(w) vec(R - R'); sqrt(w) (o - o') / L;
    sqrt(w) (sigma - sigma') / L; sqrt(w_q) dtheta_k]``.

    ``R``, ``o``, ``sigma``: the object pose seen through the root part (rotation, NAOCS origin in
    the camera, metres per NAOCS unit); primes: the :class:`PreviousSolution` (the last solution:
    a zero-velocity prior; or its constant-velocity extrapolation, :meth:`PreviousSolution.constant_velocity`:
    a prior on the change of pose and joint-state velocity). ``dtheta_k`` is the deviation of
    joint state ``k`` (:func:`joint_state_expr`): radians, or divided by ``L`` (prismatic).
    Weights ``w`` (pose) and ``w_q`` (joint states) of the :class:`PreviousSolution`, entering as the
    parameters ``sqrt_temporal_weight`` and ``sqrt_temporal_state_weight`` (either may be 0).
    Defined on the part poses, so it serves both parameterisations.
    """

    name = "temporal_prior"

    def expression(self, ctx: Context) -> ca.SX:
        st, r = ctx.structure, ctx.structure.root
        pose = [ca.vec(ctx.poses[r].R - ctx.params.get("prev_R", 3, 3)),
                (ctx.naocs_to_cam(r, ca.DM.zeros(3)) - ctx.params.get("prev_origin", 3)) / ctx.L,
                (ctx.object_scale(r) - ctx.params.get("prev_scale")) / ctx.L]
        # the parameters are the weights' square roots: sqrt(w) of a parameter has no derivative at w = 0,
        # and a zero joint-state weight with a pose weight (or the reverse) made the multipliers NaN
        out = [ctx.params.get("sqrt_temporal_weight") * ca.vertcat(*pose)]
        w_q = ctx.params.get("sqrt_temporal_state_weight")
        for k in range(st.num_joints):
            d = joint_state_expr(ctx, k) - ctx.params.get(f"prev_state{k}")
            out.append(w_q * (d if st.is_revolute(k) else d / ctx.L))
        return ca.vertcat(*out)

    def fill(self, structure: KinematicStructure, inputs: ProgramInputs) -> dict:
        prev = inputs.require("previous", self.name)
        if len(prev.joint_states) != structure.num_joints:
            raise ValueError(f"inputs.previous.joint_states: expected {structure.num_joints} states, got {len(prev.joint_states)}")
        T = prev.T_cam_naocs
        return {"sqrt_temporal_weight": np.sqrt(prev.weight), "sqrt_temporal_state_weight": np.sqrt(prev.state_weight),
                "prev_R": T.rotation, "prev_origin": T.translation, "prev_scale": T.scale,
                **{f"prev_state{k}": q for k, q in enumerate(prev.joint_states)}}
