"""The equations layer: from a formalism's symbolic system to numbers an integrator uses.

``contract`` (what a formalism returns: forms and observables), ``forms`` (the mechanical,
dae and ode forms derived once, for every formalism), ``observables`` (poses, energies and
residuals measured the same way for all), ``evaluate`` (CasADi functions through
preallocated buffers), ``compiled`` (the same functions as C), ``initial`` (a consistent
initial state), ``contacts`` (gaps and contact Jacobians for set-valued forces).
Import the contract from here: ``from workbench.equations import Equations``.
"""

from workbench.equations.contract import (
    FORMS,
    Atlas,
    ContactForm,
    DaeForm,
    Equations,
    MechanicalForm,
    MechanicalSystem,
    OdeForm,
)
from workbench.equations.forms import (
    SYMBOLIC_SOLVE_LIMIT,
    build_equations,
    build_joint_space_equations,
    constraint_acceleration_rhs,
    joint_space_system,
)
from workbench.equations.observables import (
    Observables,
    SampledObservables,
    build_observables,
    joint_residuals,
)

__all__ = [
    "FORMS",
    "SYMBOLIC_SOLVE_LIMIT",
    "Atlas",
    "ContactForm",
    "DaeForm",
    "Equations",
    "MechanicalForm",
    "MechanicalSystem",
    "Observables",
    "OdeForm",
    "SampledObservables",
    "build_equations",
    "build_joint_space_equations",
    "build_observables",
    "constraint_acceleration_rhs",
    "joint_residuals",
    "joint_space_system",
]
