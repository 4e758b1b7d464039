"""The formalism contract (docs/architecture.md, "Plugins" and "The equations contract").

A formalism plugin subclasses :class:`Formalism`, registers with
``@workbench.plugin.registry.formalism`` and:

1. sets ``name``, ``summary`` (one line) and ``Options`` (a frozen dataclass with
   defaults, validated by :func:`workbench.plugin.options.parse_options`);
2. sets ``capabilities``: the model features it handles (see :func:`model_features`);
3. implements :meth:`Formalism.forms` -> {form: index} it will provide for given
   options (the runner pairs it only with integrators accepting one of them);
4. implements :meth:`Formalism.build` (model, options) -> :class:`~workbench.equations.Equations`,
   usually by describing a :class:`~workbench.equations.MechanicalSystem` and calling
   :func:`~workbench.equations.build_equations`;
5. if it decides anything from the rank of the constraints (rows to drop as redundant, a
   velocity partition), decides it where ``workbench describe`` does: at
   :func:`workbench.mechanics.topology.rank_configurations` (model) — the model's
   ``initial_configuration``, which a problem's model carries (the problem's initial joint
   coordinates), assembled, confirmed at random assembled ones — with
   :func:`~workbench.mechanics.topology.independent_rows_at`; names the rows it removes in
   ``Equations.notes`` ("removed redundant constraint rows: ..."); and, if it keeps a
   fixed velocity partition, offers ``Equations.partition_matrices`` so runs report where
   it turns singular. The conformance kit's ``dof`` check holds it to describe's count.

6. if it enforces the constraints only approximately (a penalty or augmented-Lagrangian
   method: the constraint rows become stiff forces, the DOF count is not describe's),
   says so with :meth:`Formalism.constraint_tolerance` -> the largest constraint residual
   (m, rad, m/s) it promises over a tight integration; the conformance kit then holds it
   to that promise instead of to exact constraints (``approximation``, ``dof``,
   ``constraints``; accelerations at a consistent state are not compared, and motion
   errors may reach the declared tolerance over the model's length scale).

The forms a formalism offers (``ode``, ``dae``, ``mechanical``, :data:`workbench.equations.FORMS`)
are declared per options by :meth:`Formalism.forms` and built per model by
:meth:`Formalism.build` (the kit's ``equations`` check holds the built ones to the
declared ones; a model may add forms, never drop one). To honour the ``compile`` option
(evaluate in C rather than the CasADi virtual machine), a formalism gives
:func:`~workbench.equations.build_equations` a :class:`~workbench.equations.compiled.Compiler`
(``Compiler.from_options(options)`` reads the ``compile`` and ``compile_flags`` fields of
its options; :class:`CompileOptions` declares them), as
:func:`~workbench.equations.build_joint_space_equations` does.

A feature the formalism cannot handle raises :class:`PluginError` from :meth:`check`,
naming the formalisms that do handle it. A limit that is not one of :data:`FEATURES`
(e.g. quaternion joints, :func:`workbench.mechanics.lagrangian.quaternion_joints`) is declared by
extending :meth:`Formalism.unsupported`; the runner and the conformance suite
(:mod:`workbench.testing`, docs/plugins.md) then skip such models with that reason.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar, Literal

from workbench.errors import ConfigError, PluginError
from workbench.model import Model
from workbench.plugin.options import NoOptions, parse_options, with_unit

FEATURES = {
    "planar": "planar model",
    "spatial": "spatial model",
    "closed-loops": "loop-closing (cut) joints",
    "nonholonomic": "nonholonomic constraints (rolling, knife edge)",
    "rheonomic": "driven joints (prescribed motion)",
    "point-masses": "point masses",
    "contacts": "unilateral contacts (PlaneContact, SphereContact)",
}


def model_features(model: Model) -> set[str]:
    """The features of ``model`` that a formalism must support to handle it."""
    features = {model.kind}
    if model.cut_joints:
        features.add("closed-loops")
    if model.nonholonomic:
        features.add("nonholonomic")
    if any(j.drive is not None for j in model.joints.values()):
        features.add("rheonomic")
    if any(b.point_mass for b in model.bodies.values()):
        features.add("point-masses")
    if model.contacts or model.joint_frictions:
        features.add("contacts")
    return features


@dataclass(frozen=True)
class CompileOptions:
    """Options of every formalism: how its equations are evaluated in hot loops,
    ``compile`` = "none" (CasADi virtual machine), "jit" (C compiled with the machine's
    compiler and ``compile_flags``, cached on disk; the default "-O1" lets the workbench
    choose, :func:`workbench.equations.compiled.default_flags`; see
    :mod:`workbench.equations.compiled`)
    or "auto" (C where the run's evaluations repay the compile, decided for each run alone;
    the default of ``workbench run`` and of sweeps alike, so that the same pairing has one
    run id; see :mod:`workbench.equations.compile_policy`)."""

    compile: Literal["none", "jit", "auto"] = "auto"
    compile_flags: str = "-O1"


@dataclass(frozen=True)
class ConstraintOptions(CompileOptions):
    """Options shared by formalisms with constraint multipliers: the DAE index of the
    ``dae`` form and the Baumgarte gains of index 1 (whose system is also the ``ode`` form)."""

    index: Literal[1, 2, 3] = 3
    baumgarte_alpha: float = with_unit(10.0, "1/s")  # g'' + 2 alpha g' + beta^2 g = 0
    baumgarte_beta: float = with_unit(10.0, "1/s")

    def __post_init__(self) -> None:
        if self.baumgarte_alpha < 0 or self.baumgarte_beta < 0:
            raise ConfigError("Baumgarte gains must be >= 0")


def constrained_forms(options: ConstraintOptions) -> dict[str, int]:
    """The forms of a constrained system: dae at the index, mechanical, ode at index 1."""
    forms = {"dae": options.index, "mechanical": 0}
    if options.index == 1:
        forms["ode"] = 0
    return forms


class Formalism:
    """Base class of formalism plugins (see the module docstring)."""

    name: ClassVar[str] = ""
    summary: ClassVar[str] = ""
    Options: ClassVar[type] = NoOptions
    capabilities: ClassVar[frozenset[str]] = frozenset()

    @classmethod
    def parse_options(cls, options: Any = None) -> Any:
        return parse_options(cls.Options, options, f"formalism {cls.name!r}")

    @classmethod
    def forms(cls, options: Any) -> dict[str, int]:
        """{form name: dae index (0 for ode and mechanical)} provided for ``options``."""
        raise NotImplementedError

    @classmethod
    def constraint_tolerance(cls, options: Any) -> float | None:
        """None: the constraints hold to the integrator's tolerance (the default); a number
        > 0: they are enforced approximately (penalty, augmented Lagrangian), to this
        absolute residual (m, rad, m/s) with these ``options`` (contract item 6)."""
        return None

    @classmethod
    def unsupported(cls, model: Model) -> set[str]:
        return model_features(model) - set(cls.capabilities)

    @classmethod
    def check(cls, model: Model) -> None:
        """Raise PluginError if the model has features this formalism cannot handle."""
        missing = cls.unsupported(model)
        if missing:
            from workbench.plugin.registry import list_plugins

            feature = sorted(missing)[0]
            others = [
                info.name
                for info in list_plugins("formalism")
                if info.plugin is not None and feature in getattr(info.plugin, "capabilities", ())
            ]
            supported_by = f"; use {', '.join(others)}" if others else ""
            raise PluginError(
                f"formalism {cls.name!r} does not support {FEATURES.get(feature, feature)} "
                f"(model {model.name!r}){supported_by}"
            )

    def build(self, model: Model, options: Any = None) -> Any:
        raise NotImplementedError
