"""The ``workbench`` command line (``workbench --help``; also ``python -m workbench``).

Adding a command is adding one function decorated with ``@app.command()``. A command
raises :class:`~workbench.errors.WorkbenchError` on bad input; :class:`WorkbenchGroup`
turns it into one line on stderr and exit code 2, so no command handles errors itself.
Tables go through :func:`console` (rich); plain messages through ``typer.echo``.
"""

from __future__ import annotations

import sys
from collections.abc import Mapping
from typing import Annotated, Any

import click
import typer
from rich.console import Console
from rich.table import Table

from workbench import __version__, registry
from workbench.errors import WorkbenchError
from workbench.options import option_fields, type_name
from workbench.registry import KINDS, Kind, PluginInfo, describe_kind

EXIT_BAD_INPUT = 2


def one_line(error: BaseException) -> str:
    """An error message on a single line (continuation lines joined with ' | ')."""
    lines = [line.strip() for line in str(error).splitlines() if line.strip()]
    return " | ".join(lines) or type(error).__name__


def fail(error: WorkbenchError) -> typer.Exit:
    """Print ``error`` as one line on stderr; the caller raises the returned Exit(2)."""
    typer.echo(f"error: {one_line(error)}", err=True)
    return typer.Exit(EXIT_BAD_INPUT)


class WorkbenchGroup(typer.core.TyperGroup):
    """The one place where a WorkbenchError becomes a one-line message and exit code 2."""

    def invoke(self, ctx: click.Context) -> Any:
        try:
            return super().invoke(ctx)
        except WorkbenchError as error:
            raise fail(error) from None


app = typer.Typer(
    cls=WorkbenchGroup,
    name="workbench",
    help="Compare formalisms and integrators for multibody dynamics.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)


def console() -> Console:
    """A rich console on the current stdout (so test runners can capture it).

    Markup is off: plugin summaries and error messages may contain brackets.
    """
    return Console(file=sys.stdout, highlight=False, markup=False)


def _version(value: bool) -> None:
    if value:
        typer.echo(f"mbs-workbench {__version__}")
        raise typer.Exit()


@app.callback()
def _root(
    version: Annotated[
        bool,
        typer.Option("--version", callback=_version, is_eager=True, help="Print the version."),
    ] = False,
) -> None:
    """Compare formalisms and integrators for multibody dynamics."""


# -- what a plugin declares ------------------------------------------------------------
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
    table.add_column("capabilities")
    table.add_column("status")
    for info in infos:
        summary = "" if info.plugin is None else info.summary
        status = _status(info)
        style = "red" if info.plugin is None else None
        table.add_row(info.name, summary, capabilities_text(info.plugin), status, style=style)
    return table


# -- commands -------------------------------------------------------------------------
@app.command("list")
def list_command(
    kind: Annotated[
        str | None,
        typer.Argument(help="problems, formalisms or integrators (default: all three)."),
    ] = None,
) -> None:
    """List the registered plugins: name, summary, capabilities and status."""
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
    name: Annotated[str, typer.Argument(help="A problem, formalism or integrator name.")],
) -> None:
    """Describe one plugin: summary, options, capabilities; for a problem also its model."""
    kind, plugin = registry.any_plugin(name)
    out = console()
    out.print(f"{name} ({kind}, {plugin.__module__})", style="bold")
    summary = getattr(plugin, "summary", "")
    if summary:
        out.print(summary)
    if kind == "problem" and getattr(plugin, "source", ""):
        out.print(f"source: {plugin.source}")
    out.print(f"capabilities: {capabilities_text(plugin)}")
    out.print(_options_table(plugin))
    if kind == "problem":
        out.print(_problem_table(plugin))


def _options_table(plugin: type) -> Table | str:
    options_class = getattr(plugin, "Options", None)
    rows = option_fields(options_class) if options_class is not None else []
    if not rows:
        return "options: none"
    table = Table(title="options", title_justify="left")
    table.add_column("name", no_wrap=True)
    table.add_column("type")
    table.add_column("default")
    for name, annotation, default in rows:
        table.add_row(name, type_name(annotation), repr(default))
    return table


def _problem_table(problem_class: type) -> Table:
    """The problem's model, built with default options, and its topology."""
    problem = problem_class()
    model = problem.model()
    table = Table(title="model", title_justify="left", show_header=False)
    table.add_column("property", no_wrap=True)
    table.add_column("value")
    table.add_row("kind", model.kind)
    table.add_row("bodies", f"{len(model.bodies)}: {', '.join(model.bodies)}")
    table.add_row("joints", f"{len(model.joints)}: {', '.join(model.joints)}")
    for label, value in _topology_rows(model):
        table.add_row(label, value)
    invariants = (["energy"] if problem.conservative else []) + [
        invariant.name for invariant in problem.invariants()
    ]
    table.add_row("invariants", ", ".join(invariants) or "none")
    reference = problem.reference()
    table.add_row("reference", reference.kind if reference is not None else "none")
    table.add_row("time span", f"{problem.t_start:g} .. {problem.t_end:g} s")
    return table


def _topology_rows(model: Any) -> list[tuple[str, str]]:
    """DOF, loops and constraint counts from workbench.topology; a note if it is missing."""
    try:
        from workbench.topology import analyze
    except ImportError:
        return [
            ("loops", str(len(model.cut_joints))),
            ("nonholonomic constraints", str(len(model.nonholonomic))),
            ("DOF", "unknown (workbench.topology not available)"),
        ]
    topology = analyze(model)
    dof = topology.dof
    if dof is None:
        dof_text = f"{topology.dof_gruebler} (Gruebler count; rank not computed)"
    elif dof != topology.dof_gruebler:
        dof_text = f"{dof} (Gruebler count {topology.dof_gruebler})"
    else:
        dof_text = str(dof)
    return [
        ("tree / cut joints", f"{_count(topology.tree_joints)} / {_count(topology.cut_joints)}"),
        ("loops", str(topology.n_loops)),
        ("DOF", dof_text),
        ("redundant constraints", str(topology.redundant_constraints)),
        ("nonholonomic rows", str(topology.n_nonholonomic)),
    ]


def _count(joints: Any) -> str:
    return str(joints) if isinstance(joints, int) else str(len(joints))


# -- reports --------------------------------------------------------------------------
@app.command()
def report(
    results_path: Annotated[
        str,
        typer.Argument(
            metavar="RESULTS",
            help="A results directory (the output of `workbench sweep`) or a results.parquet.",
        ),
    ],
    out: Annotated[
        str | None,
        typer.Option("-o", "--out", help="Report directory (default: RESULTS/report)."),
    ] = None,
) -> None:
    """Write an HTML report (figures, tables as CSV/Markdown/LaTeX) of a results directory."""
    import shlex
    import warnings
    from pathlib import Path

    from workbench.errors import ConfigError
    from workbench.report import write_report
    from workbench.store import load_results, load_series

    source = Path(results_path)
    if not source.exists():
        raise ConfigError(f"no results at {source}: give the output directory of `workbench sweep`")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        frame = load_results(source)
    for warning in caught:
        typer.echo(f"warning: {warning.message}", err=True)
    if len(frame) == 0:
        raise ConfigError(f"no result rows in {source}: run `workbench sweep --out {source}` first")
    directory = source if source.is_dir() else source.parent
    target = Path(out) if out else directory / "report"

    def series_loader(run_id: str) -> Any:
        try:
            return load_series(directory, run_id)
        except (ConfigError, OSError, ValueError):  # no or unreadable series: no curve
            return None

    command = shlex.join(["workbench", "report", str(results_path), "-o", str(target)])
    index = write_report(frame, series_loader, target, command)
    typer.echo(f"report: {index}")


def main() -> None:
    """Console-script entry point (``workbench``)."""
    try:
        app()
    except WorkbenchError as error:  # raised outside a command (e.g. by a callback)
        sys.exit(fail(error).exit_code)


if __name__ == "__main__":
    main()
