"""Integrator ``lie-generalized-alpha``: Bruls, Cardona & Arnold (2012) on the index-3 form.

O. Bruls, A. Cardona, M. Arnold, "Lie group generalized-alpha time integration of
constrained flexible multibody systems", Mech. Mach. Theory 48 (2012) 121-137. The
configuration lives on SO(3)^k x R^n: the Euler parameters p of every rotation block of
the mechanical form (:attr:`~workbench.equations.MechanicalForm.rotation_blocks`, with the
body-frame angular velocity omega, p' = 1/2 p * (0, omega)) and the other coordinates. The
step is that of ``generalized-alpha`` (:mod:`.generalized_alpha`, same Chung-Hulbert
parameters from ``rho_inf``, same scaled index-3 constraint rows, step from rtol, adaptive
option) except for the position update, taken on the Lie algebra:

    increment = v_n + h (1/2 - beta) a_n + h beta a_{n+1}                  (in R^nv)
    p_{n+1} = p_n * exp(h increment[omega])     (rotation blocks, multiplicative)
    x_{n+1} = x_n + h (H_mid increment + f_mid)[x]                 (every other row)

with exp the exponential map of SO(3) as a unit quaternion
(:func:`workbench.numerics.rotations.quaternion_exp`). The product of unit quaternions is
a unit quaternion, so |p| = 1 holds to round-off with no projection and no norm
constraint; velocities and accelerations stay in R^nv and are updated additively.

Newton's iteration matrix is generalized-alpha's with d q_{n+1} / d increment = h B,
B = H(p_{n+1}) T(h increment[omega]) in the rotation rows (T the tangent operator of the
exponential map, :func:`~workbench.numerics.rotations.tangent_operator`) and H_mid
elsewhere: the exact derivative of the update, composed with the derivatives dr/dq and
dg/dq the mechanical form gives in the embedding R^4 of each quaternion (exact along the
unit sphere, where the iterates stay). Positions and velocities converge at order 2
(BCA 2012, and tests/test_lie_generalized_alpha.py).

Applicability (``incompatibility``): every Euler-parameter slice of the equations
(``Equations.quaternion_slices``) must be a rotation block, i.e. the formalism states
which velocities rotate it (joint-space ``recursive`` and ``minimal-ode`` and
``absolute-dae`` do; formalisms whose velocities are projected or partitioned do not).
Models without rotations are integrated exactly as ``generalized-alpha`` integrates them.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from workbench.equations import Equations
from workbench.numerics.rotations import (
    quaternion_exp,
    quaternion_multiply,
    quaternion_rate_matrix,
    tangent_operator,
)
from workbench.plugin.registry import integrator
from workbench.plugins.integrators.generalized_alpha import GeneralizedAlpha


@integrator
class LieGeneralizedAlpha(GeneralizedAlpha):
    name = "lie-generalized-alpha"
    summary = (
        "Lie-group generalized-alpha (Bruls-Cardona-Arnold 2012): rotations by the "
        "exponential map, no norm constraint"
    )
    accepts = {"mechanical": 3}

    def incompatibility(self, equations: Equations, options: Any) -> str | None:
        mech = equations.forms.get("mechanical")
        if mech is None:
            return "needs the mechanical form"
        stated = {(q_slice.start, q_slice.stop) for q_slice, _ in mech.rotation_blocks}
        for part in equations.quaternion_slices:
            if (part.start, part.stop) not in stated:
                return (
                    f"formalism {equations.formalism!r} keeps Euler parameters in "
                    f"q[{part.start}:{part.stop}] but does not state which velocities rotate "
                    "them (no rotation block); use recursive, minimal-ode (loops='augmented') "
                    "or absolute-dae"
                )
        return None

    def _setup(
        self, options: Any, mech: Any, nq: int, nv: int, nc: int, m: int, identity: bool
    ) -> None:
        super()._setup(options, mech, nq, nv, nc, m, identity)
        self.blocks = list(mech.rotation_blocks)

    def _advance(
        self, q: np.ndarray, h: float, increment: np.ndarray, context: tuple[np.ndarray, ...]
    ) -> np.ndarray:
        """Rotation blocks p_n * exp(h increment[omega]); other rows generalized-alpha's."""
        q_new = super()._advance(q, h, increment, context)
        for q_slice, v_slice in self.blocks:
            q_new[q_slice] = quaternion_multiply(q[q_slice], quaternion_exp(h * increment[v_slice]))
        return q_new

    def _position_tangent(
        self, q: np.ndarray, h: float, increment: np.ndarray, context: tuple[np.ndarray, ...]
    ) -> np.ndarray:
        """H_mid, with H(p_{n+1}) T(h increment[omega]) in the rotation blocks."""
        tangent = np.array(context[0], dtype=float)
        for q_slice, v_slice in self.blocks:
            tangent[q_slice, :] = 0.0
            tangent[q_slice, v_slice] = np.asarray(
                quaternion_rate_matrix(q[q_slice], "body"), dtype=float
            ) @ tangent_operator(h * increment[v_slice])
        return tangent
