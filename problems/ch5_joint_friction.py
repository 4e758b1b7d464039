"""Coulomb friction in a joint (book 5.4.2; docs/nonsmooth.md): a closed loop whose prismatic
joint holds the set-valued force, for the contact integrators beside bilateral constraints.

``slider-crank-friction`` -- the point-mass slider-crank of book 5.7.2
(``point-mass-slider-crank``: crank r = 0.1 m carrying a 0.5 kg pin, a light 0.3 m rod, a
1 kg piston on a horizontal slide; gravity -y; crank at 0.5 rad turning at 8 rad/s) with
Coulomb friction of bound F = 2 N in the piston's slide. The friction does work only where
the piston slides, so the energy obeys E0 - E(t) = F * (distance the piston slid by t);
at each dead centre the piston's rate turns whatever the friction (the crank carries it
through), and the friction turns with it. The run's own piston path gives that balance
(tests/test_joint_friction.py checks it). No closed-form trajectory exists; the reference is
stored (references/slider-crank-friction.npz): event-driven on minimal-ode at rtol 1e-12,
confirmed by event-driven on absolute-dae at 1e-11 to 4.8e-11 L, its stated accuracy.
"""

from __future__ import annotations

import workbench.plugin.registry
from workbench.model import Model
from workbench.problems.ch5_point_masses import PointMassSliderCrank

SLIDE_FRICTION = 2.0  # N, the bound of the Coulomb force in the piston's slide


@workbench.plugin.registry.problem
class SliderCrankFriction(PointMassSliderCrank):
    name = "slider-crank-friction"
    summary = "Point-mass slider-crank with Coulomb friction (2 N) in the piston's slide"
    source = "book 5.7.2 with 5.4.2 (friction in a joint)"
    t_end = 2.0
    n_samples = 201
    conservative = False

    def model(self) -> Model:
        model = super().model()
        model.add_joint_friction("slide", SLIDE_FRICTION)
        return model
