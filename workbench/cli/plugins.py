"""Commands about plugins: ``workbench list``, ``describe`` and ``new``."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Annotated, Any

import typer
from rich.table import Table

from workbench.cli.app import app, console, option_value
from workbench.cli.plugin_flags import NoLocalPluginsOption, PluginsOption, plugins_from_flags
from workbench.cli.robot_files import ALLOW_ROOT_OPTION, PACKAGE_PATH_OPTION
from workbench.plugin import registry
from workbench.plugin.options import option_fields, option_units, type_name
from workbench.plugin.registry import KINDS, Kind, PluginInfo, describe_kind


def capabilities_text(plugin: type | None) -> str:
    """A plugin's declared capabilities on one line; '-' when it declares none.

    Formalisms declare ``capabilities`` (model features handled), integrators ``accepts``
    (form -> maximum differentiation index).
    """
    if plugin is None:
        return "-"
    parts = []
    capabilities = getattr(plugin, "capabilities", None)
    if capabilities:
        parts.append(", ".join(sorted(map(str, capabilities))))
    accepts = getattr(plugin, "accepts", None)
    if isinstance(accepts, Mapping) and accepts:
        parts.append(", ".join(f"{form} (index <= {index})" for form, index in accepts.items()))
    elif accepts:
        parts.append(", ".join(sorted(map(str, accepts))))
    return "; ".join(parts) or "-"


def _status(info: PluginInfo) -> str:
    return f"broken: {info.error_line}" if info.plugin is None else "ok"


def _plugin_table(kind: Kind, infos: list[PluginInfo]) -> Table:
    table = Table(title=f"{kind}s", title_justify="left")
    table.add_column("name", no_wrap=True)
    table.add_column("summary")
    declared = kind != "problem"  # problems declare none: a column of '-' said nothing
    if declared:
        table.add_column("capabilities")
    table.add_column("status")
    for info in infos:
        summary = "" if info.plugin is None else info.summary
        capabilities = [capabilities_text(info.plugin)] if declared else []
        style = "red" if info.plugin is None else None
        table.add_row(info.name, summary, *capabilities, _status(info), style=style)
    return table


@app.command("list")
def list_command(
    kind: Annotated[
        str | None,
        typer.Argument(help="problems, formalisms or integrators (default: all three)."),
    ] = None,
    plugins: PluginsOption = None,
    no_local_plugins: NoLocalPluginsOption = False,
) -> None:
    """List the registered plugins: name, summary, capabilities and status."""
    plugins_from_flags(plugins, no_local_plugins)
    kinds = [describe_kind(kind)] if kind is not None else list(KINDS)
    out = console()
    for each in kinds:
        infos = registry.REGISTRY.list(each)
        if infos:
            out.print(_plugin_table(each, infos))
        else:
            out.print(f"no {each}s registered")


@app.command()
def describe(
    name: Annotated[
        str,
        typer.Argument(
            help="A problem, formalism or integrator name, a robot file, or MODULE_OR_FILE:Class."
        ),
    ],
    option: Annotated[
        list[str] | None,
        typer.Option("-o", "--option", help="A problem's option NAME=VALUE (e.g. -o n=40)."),
    ] = None,
    package_path: Annotated[list[str] | None, PACKAGE_PATH_OPTION] = None,
    allow_root: Annotated[list[str] | None, ALLOW_ROOT_OPTION] = None,
    plugins: PluginsOption = None,
    no_local_plugins: NoLocalPluginsOption = False,
) -> None:
    """Describe one plugin: summary, options, capabilities; for a problem also its model."""
    from workbench.plugin.robot_problem import robot_file_problem

    _, (name,) = plugins_from_flags(plugins, no_local_plugins, name)
    name, option = robot_file_problem(name, option or [], package_path, allow_root)
    kind, plugin = registry.any_plugin(name)
    options = _problem_options(name, kind, option)
    model_tables = []  # a problem's model first: a file that does not read is one line alone
    if kind == "problem":
        problem = plugin(options)
        model_tables = [_problem_table(problem), _parameters_table(problem)]
    out = console()
    out.print(f"{name} ({kind}, {plugin.__module__})", style="bold")
    summary = getattr(plugin, "summary", "")
    if summary:
        out.print(summary)
    if kind == "problem" and getattr(plugin, "source", ""):
        out.print(f"source: {plugin.source}")
    out.print(f"capabilities: {capabilities_text(plugin)}")
    out.print(_options_table(plugin))
    for table in model_tables:
        out.print(table)


def _problem_options(name: str, kind: str, assignments: list[str]) -> dict[str, Any]:
    """``-o NAME=VALUE`` of ``describe``: options of the problem described."""
    from workbench.errors import ConfigError

    if assignments and kind != "problem":
        article = "an" if kind[0] in "aeiou" else "a"
        raise ConfigError(
            f"describe {name}: -o sets a problem's options; {name} is {article} {kind} "
            f"(its options go to `workbench run PROBLEM ... -o NAME=VALUE`)"
        )
    options = {}
    for assignment in assignments:
        option, equals, value = assignment.partition("=")
        if not equals or not option.strip():
            raise ConfigError(f"-o {assignment!r}: expected NAME=VALUE (e.g. -o n=40)")
        options[option.strip().removeprefix("problem.")] = option_value(value.strip())
    return options


def _options_table(plugin: type) -> Table | str:
    options_class = getattr(plugin, "Options", None)
    rows = option_fields(options_class) if options_class is not None else []
    if not rows:
        return "options: none"
    units = option_units(options_class)
    table = Table(title="options", title_justify="left")
    table.add_column("name", no_wrap=True)
    table.add_column("type")
    table.add_column("default")
    if any(units.values()):
        table.add_column("unit")
    for name, annotation, default in rows:
        unit = [units.get(name, "")] if any(units.values()) else []
        table.add_row(name, type_name(annotation), repr(default), *unit)
    return table


def _problem_table(problem: Any) -> Table:
    """The problem's model, built with the options given, and its topology."""
    model = problem.model()
    table = Table(title="model", title_justify="left", show_header=False)
    table.add_column("property", no_wrap=True)
    table.add_column("value")
    table.add_row("kind", model.kind)
    table.add_row("bodies", f"{len(model.bodies)}: {_first_names(model.bodies)}")
    table.add_row("joints", f"{len(model.joints)}: {_first_names(model.joints)}")
    for label, value in _topology_rows(problem, model):
        table.add_row(label, value)
    invariants = (["energy"] if problem.conservative else []) + [
        invariant.name for invariant in problem.invariants()
    ]
    table.add_row("invariants", ", ".join(invariants) or "none")
    from workbench.execution.references import given_reference

    reference = given_reference(problem)
    table.add_row("reference", reference.kind if reference is not None else "none")
    table.add_row("time span", f"{problem.t_start:g} .. {problem.t_end:g} s")
    for label, value in problem.describe_rows():
        table.add_row(label, value)
    return table


def _parameters_table(problem: Any) -> Table:
    """The model's physical parameters (SI units) and the problem's initial condition, each
    joint's values with their units (how spherical and free joints order theirs, once)."""
    from workbench.model.parameters import QUATERNION_STATE, joint_state, model_parameters

    table = Table(title="parameters (SI units)", title_justify="left")
    for column in ("element", "quantity", "value"):
        table.add_column(column)
    model = problem.model()
    rows = model_parameters(model)
    elements = list(dict.fromkeys(element for element, _, _ in rows))
    shown = set(elements[:LISTED])
    for row in rows:
        if row[0] in shown:
            table.add_row(*row)
    if len(elements) > LISTED:  # a 10,000-link robot: 30,000 rows are not read, only printed
        more = len(elements) - LISTED
        table.add_row("...", f"{more} more elements", "not listed (the first ones are above)")
    types = {name: joint.type for name, joint in model.joints.items()}
    for label, values, velocities, none in (
        ("initial joint coordinates", problem.initial_joint_coordinates(), False, "neutral"),
        ("initial joint velocities", problem.initial_joint_velocities(), True, "at rest"),
    ):
        text = ", ".join(
            f"{joint} = {joint_state(types.get(joint, ''), value, velocities)}"
            for joint, value in values.items()
        )
        table.add_row("initial state", label, text or f"none given: {none}")
    if model.cut_joints or model.nonholonomic:
        table.add_row("initial state", "joints not listed",
                      "start neutral / at rest; the whole state is then projected onto the "
                      "loop-closure and nonholonomic constraints")  # fmt: skip
    if {"spherical", "free"} & set(types.values()):
        table.add_row("initial state", "spherical and free joints", QUATERNION_STATE)
    return table


LISTED = 100
"""Elements listed by name in ``describe`` (a 10,000-link chain is described in seconds)."""


def _first_names(names: Any) -> str:
    names = list(names)
    listed = ", ".join(names[:LISTED])
    return listed + (f", ... ({len(names) - LISTED} more)" if len(names) > LISTED else "")


def _topology_rows(problem: Any, model: Any) -> list[tuple[str, str]]:
    """DOF, loops and constraint counts from workbench.mechanics.topology; a note if it is missing.

    The rank is taken at the problem's initial configuration (the model carries it), where
    every formalism takes it: the neutral one of a closed loop can be folded (a four-link
    loop with all angles zero), where W loses rank."""
    try:
        from workbench.mechanics.topology import analyze
    except ImportError:
        return [
            ("loops", str(len(model.cut_joints))),
            ("nonholonomic constraints", str(len(model.nonholonomic))),
            ("DOF", "unknown (workbench.mechanics.topology not available)"),
        ]
    topology = analyze(model)  # at model.initial_configuration, the problem's
    dof = topology.dof
    if dof is None:
        dof_text = f"{topology.dof_gruebler} (Gruebler count; rank not computed)"
    elif dof != topology.dof_gruebler:
        dof_text = f"{dof} (Gruebler count {topology.dof_gruebler})"
    else:
        dof_text = str(dof)
    if dof is not None:  # the finding a run's initial state would raise
        from workbench.equations.initial import model_motion_without_inertia, singular_mass_finding

        t0 = float(problem.t_start)
        names = model_motion_without_inertia(model, t0, topology.configuration)
        if names:
            dof_text += f"; {singular_mass_finding(names, t0)}"
    return [
        ("tree / cut joints", f"{_count(topology.tree_joints)} / {_count(topology.cut_joints)}"),
        ("loops", str(topology.n_loops)),
        ("DOF", dof_text),
        ("redundant constraints", str(topology.redundant_constraints)),
        ("nonholonomic rows", str(topology.n_nonholonomic)),
    ]


def _count(joints: Any) -> str:
    return str(joints) if isinstance(joints, int) else str(len(joints))


@app.command("new")
def new(
    kind: Annotated[str, typer.Argument(help="formalism, integrator or problem.")],
    name: Annotated[str, typer.Argument(help="The plugin name, e.g. my-formalism.")],
    package: Annotated[
        str | None,
        typer.Option("--package", help="Write a separate installable package into this directory."),
    ] = None,
    force: Annotated[bool, typer.Option("--force", help="Overwrite existing files.")] = False,
    spatial: Annotated[
        bool,
        typer.Option("--spatial", help="A problem: spatial placeholder (a spherical joint)."),
    ] = False,
) -> None:
    """Write a ready-to-edit plugin: module, conformance test (and with --package, a package)."""
    from workbench.plugin.scaffold import scaffold

    written = scaffold(describe_kind(kind), name, package=package, force=force, spatial=spatial)
    for path in written.files:
        typer.echo(f"wrote {path}")
    typer.echo("next: " + "\n      ".join(written.next_steps))
