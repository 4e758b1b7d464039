"""The model layer: a mechanism described once, for every formalism (docs/architecture.md,
"The model").

``elements`` holds the plain data (frames, bodies, joints, forces, constraints), ``model``
the :class:`Model` that gathers and validates them, ``validation`` the checks that name
each fault and its fix, ``parameters`` the rows ``workbench describe`` prints. Import the
names from here: ``from workbench.model import Model, Frame``.
"""

from workbench.model.elements import (
    GROUND,
    JOINT_TYPES,
    PLANAR_JOINT_TYPES,
    AppliedForce,
    Body,
    Contact,
    Drive,
    ForceElement,
    Frame,
    Joint,
    JointForce,
    JointFriction,
    JointSpringDamper,
    JointType,
    KnifeEdge,
    NonholonomicConstraint,
    PlaneContact,
    RollingDisk,
    RollingSphere,
    Shape,
    SphereContact,
    SpringDamper,
)
from workbench.model.model import Model

__all__ = [
    "GROUND",
    "JOINT_TYPES",
    "PLANAR_JOINT_TYPES",
    "AppliedForce",
    "Body",
    "Contact",
    "Drive",
    "ForceElement",
    "Frame",
    "Joint",
    "JointForce",
    "JointSpringDamper",
    "JointType",
    "KnifeEdge",
    "Model",
    "NonholonomicConstraint",
    "JointFriction",
    "PlaneContact",
    "RollingDisk",
    "RollingSphere",
    "Shape",
    "SphereContact",
    "SpringDamper",
]
