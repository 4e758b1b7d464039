"""What is registered: ``list_plugins(kind)`` and ``describe(name)``."""

from __future__ import annotations

import html
import os
from dataclasses import dataclass, field
from typing import Any

import pandas as pd

from workbench.errors import PluginError
from workbench.plugin import registry
from workbench.plugin.options import option_fields, option_units, type_name


def list_plugins(kind: str | None = None) -> pd.DataFrame:
    """The registered plugins, as ``workbench list [KIND]`` prints them: one row a plugin
    (kind, name, summary, status, module); ``kind``: problems, formalisms or
    integrators (default all three). A broken plugin is listed with its error as status.

    (Not ``workbench.problems()``: ``workbench.problems`` is the catalog's package.)"""
    if kind is not None and not isinstance(kind, str):
        raise PluginError(
            f"list_plugins: kind is problems, formalisms or integrators (or None: all), "
            f"not {kind!r}"
        )
    registry.REGISTRY.discover()
    kinds = [registry.describe_kind(kind)] if kind is not None else list(registry.KINDS)
    rows = [
        {
            "kind": info.kind,
            "name": info.name,
            "summary": getattr(info.plugin, "summary", "") if info.plugin else "",
            "status": info.status,
            "module": info.module,
        }
        for each in kinds
        for info in registry.list_plugins(each)
    ]
    return pd.DataFrame(rows, columns=["kind", "name", "summary", "status", "module"])


@dataclass
class Description:
    """What ``workbench describe NAME`` prints, as data: shown as tables in Jupyter.

    ``options``: name, type and default of each option (a problem's also its ``value``,
    the one given or the default); ``model`` (problems only): the
    model built with the options given, and ``facts``: its bodies, joints, topology,
    reference and time span."""

    name: str
    kind: str
    plugin: type
    options: pd.DataFrame
    model: Any = None
    facts: dict[str, str] = field(default_factory=dict)

    @property
    def summary(self) -> str:
        return getattr(self.plugin, "summary", "")

    def __repr__(self) -> str:
        lines = [f"{self.name} ({self.kind}): {self.summary}"]
        lines += [f"  {key}: {value}" for key, value in self.facts.items()]
        for name, row in self.options.iterrows():
            value = row.get("value", row["default"])
            default = "" if _same(value, row["default"]) else f" (default {row['default']!r})"
            unit = f" {row['unit']}" if row.get("unit") else ""
            lines.append(f"  option {name} ({row['type']}) = {value!r}{unit}{default}")
        return "\n".join(lines)

    def _repr_html_(self) -> str:
        facts = "".join(
            f"<tr><th style='text-align:left'>{html.escape(k)}</th>"
            f"<td style='text-align:left'>{html.escape(v)}</td></tr>"
            for k, v in self.facts.items()
        )
        options = self.options.to_html() if len(self.options) else "<p>no options</p>"
        model = self.model._repr_html_() if self.model is not None else ""
        return (
            f"<h4>{html.escape(self.name)} <small>({self.kind})</small></h4>"
            f"<p>{html.escape(self.summary)}</p>"
            + (f"<table>{facts}</table>" if facts else "")
            + model
            + f"<b>options</b>{options}"
        )


def describe(name: str | type, **options: Any) -> Description:
    """Describe a registered problem, formalism or integrator (a name, or the class), or
    a robot file (``.urdf``, MJCF ``.xml``);
    ``options`` are a problem's (e.g. ``describe(NAME, n=5)``)."""
    from workbench.api.runs import robot_file

    if not isinstance(name, str | os.PathLike | type):
        raise PluginError(
            f"describe: expected the name of a problem, formalism or integrator, a plugin "
            f"class or a robot file, not {type(name).__name__} {name!r}"
        )
    if isinstance(name, os.PathLike):
        name = os.fspath(name)
    registry.REGISTRY.discover()
    if robot_file(name, None)[1] is not None:  # a robot file: the robot problem of it
        name, given = robot_file(name, None)
        options = given | options
    if isinstance(name, type):
        plugin = name
        kind = next((k for k in registry.KINDS if issubclass_of_kind(plugin, k)), None)
        if kind is None:
            raise PluginError(
                f"describe: {plugin.__name__} is not a Problem, Formalism or Integrator class"
            )
        name = plugin.name
    else:
        kind, plugin = registry.any_plugin(name)
    options_class = getattr(plugin, "Options", None) or _NoOptions
    units = option_units(options_class)
    rows = [
        {"name": n, "type": type_name(t), "unit": units.get(n, ""), "default": d}
        for n, t, d in option_fields(options_class)
    ]
    table = pd.DataFrame(rows, columns=["name", "type", "unit", "default"]).set_index("name")
    description = Description(name, kind, plugin, table)
    if kind == "problem":
        problem = plugin(options)
        values = getattr(problem, "options", None)  # the values in use: given or default
        defaults = zip(table.index, table["default"], strict=True)
        table["value"] = [getattr(values, n, d) for n, d in defaults]
        description.model = problem.model()
        description.facts = model_facts(problem, description.model)
    elif options:
        from workbench.errors import ConfigError

        raise ConfigError(f"describe {name}: options describe a problem; {name} is a {kind}")
    return description


def issubclass_of_kind(plugin: type, kind: str) -> bool:
    from workbench.plugin.formalism import Formalism
    from workbench.plugin.integrator import Integrator
    from workbench.plugin.problem import Problem

    base = {"problem": Problem, "formalism": Formalism, "integrator": Integrator}[kind]
    return issubclass(plugin, base)


def _same(a: Any, b: Any) -> bool:
    """a == b, NaN equal to NaN (an option whose default is NaN)."""
    try:
        return bool(a == b) or (a != a and b != b)
    except (TypeError, ValueError):  # arrays and the like: shown as given
        return False


@dataclass(frozen=True)
class _NoOptions:
    pass


def model_facts(problem: Any, model: Any) -> dict[str, str]:
    """A problem's model in a few lines: kind, bodies, joints, loops, DOF (and whether the
    mass matrix is singular on the motions it allows, as a run would find), time span."""
    from workbench.equations.initial import model_motion_without_inertia, singular_mass_finding
    from workbench.mechanics.topology import analyze

    topology = analyze(model)
    dof = str(topology.dof if topology.dof is not None else topology.dof_gruebler)
    t0 = float(problem.t_start)
    names = model_motion_without_inertia(model, t0, topology.configuration)
    if names:
        dof += f"; {singular_mass_finding(names, t0)}"
    facts = {
        "kind": model.kind,
        "bodies": f"{len(model.bodies)}: {', '.join(model.bodies)}",
        "joints": f"{len(model.joints)}: {', '.join(model.joints)}",
        "loops": str(topology.n_loops),
        "DOF": dof,
        "nonholonomic rows": str(topology.n_nonholonomic),
        "conservative": "yes" if problem.conservative else "no",
        "time span": f"{problem.t_start:g} .. {problem.t_end:g} s",
    }
    if model.contacts:
        facts["contacts"] = f"{len(model.contacts)}: {', '.join(c.name for c in model.contacts)}"
    if model.joint_frictions:
        facts["joint friction"] = ", ".join(
            f"{f.joint} (bound {f.bound:g})" for f in model.joint_frictions
        )
    return facts
