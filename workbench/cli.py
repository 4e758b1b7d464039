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

from workbench import __version__
from workbench.errors import WorkbenchError
from workbench.plugin import registry
from workbench.plugin.options import option_fields, type_name
from workbench.plugin.registry import KINDS, Kind, PluginInfo, describe_kind

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
        out.print(_parameters_table(plugin))


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
    for label, value in _topology_rows(problem, model):
        table.add_row(label, value)
    invariants = (["energy"] if problem.conservative else []) + [
        invariant.name for invariant in problem.invariants()
    ]
    table.add_row("invariants", ", ".join(invariants) or "none")
    from workbench.runs.references import given_reference

    reference = given_reference(problem)
    table.add_row("reference", reference.kind if reference is not None else "none")
    table.add_row("time span", f"{problem.t_start:g} .. {problem.t_end:g} s")
    return table


def _parameters_table(problem_class: type) -> Table:
    """The model's physical parameters (SI units) and the problem's initial condition."""
    from workbench.model.parameters import model_parameters

    problem = problem_class()
    table = Table(title="parameters (SI units)", title_justify="left")
    for column in ("element", "quantity", "value"):
        table.add_column(column)
    for row in model_parameters(problem.model()):
        table.add_row(*row)
    for label, values in (
        ("initial joint coordinates", problem.initial_joint_coordinates()),
        ("initial joint velocities", problem.initial_joint_velocities()),
    ):
        text = ", ".join(f"{joint} = {_values(value)}" for joint, value in values.items())
        table.add_row("initial state", label, text or "neutral / at rest")
    return table


def _values(value: Any) -> str:
    import numpy as np

    array = np.atleast_1d(np.asarray(value, dtype=float))
    text = ", ".join(f"{x:.4g}" for x in array)
    return text if array.size == 1 else f"({text})"


def _topology_rows(problem: Any, model: Any) -> list[tuple[str, str]]:
    """DOF, loops and constraint counts from workbench.mechanics.topology; a note if it is missing.

    The rank is taken at the problem's initial configuration: the neutral one of a closed
    loop can be folded (a four-link loop with all angles zero), where W loses rank."""
    try:
        from workbench.mechanics.topology import analyze
    except ImportError:
        return [
            ("loops", str(len(model.cut_joints))),
            ("nonholonomic constraints", str(len(model.nonholonomic))),
            ("DOF", "unknown (workbench.mechanics.topology not available)"),
        ]
    from workbench.mechanics.kinematics import TreeKinematics, initial_joint_values

    q0 = initial_joint_values(
        model, TreeKinematics(model), problem.initial_joint_coordinates(), velocities=False
    )
    topology = analyze(model, q=q0)
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


# -- runs, sweeps, results ---------------------------------------------------------------
def _option_value(text: str) -> Any:
    """A ``-o`` value as TOML (1, 1e-3, true, "x", [1, 2]); a bare word stays a string."""
    import tomllib

    try:
        return tomllib.loads(f"value = {text}")["value"]
    except tomllib.TOMLDecodeError:
        return text


def _run_options(assignments: list[str]) -> dict[str, dict[str, Any]]:
    """``-o [problem.|formalism.|integrator.]NAME=VALUE`` -> options per plugin kind.

    A name without a prefix goes to the first kind whose options declare it (formalism,
    then integrator, then problem) - resolved in :func:`_assign_options`.
    """
    from workbench.errors import ConfigError

    parsed: dict[str, dict[str, Any]] = {"problem": {}, "formalism": {}, "integrator": {}, "": {}}
    for assignment in assignments:
        name, equals, value = assignment.partition("=")
        if not equals or not name.strip():
            raise ConfigError(f"-o {assignment!r}: expected NAME=VALUE (e.g. -o index=1)")
        kind, dot, option = name.strip().rpartition(".")
        if dot and kind not in ("problem", "formalism", "integrator"):
            raise ConfigError(
                f"-o {assignment!r}: the prefix must be problem., formalism. or integrator."
            )
        parsed[kind][option] = _option_value(value.strip())
    return parsed


def _assign_options(parsed: dict[str, dict[str, Any]], classes: dict[str, type]) -> None:
    from workbench.errors import ConfigError

    for option, value in parsed.pop("").items():
        for kind in ("formalism", "integrator", "problem"):
            names = [n for n, _, _ in option_fields(classes[kind].Options)]
            if option in names:
                parsed[kind][option] = value
                break
        else:
            raise ConfigError(
                f"-o {option}: no option of that name in the problem, formalism or integrator; "
                "see `workbench describe NAME`"
            )


@app.command()
def run(
    problem: Annotated[str, typer.Argument(help="Problem name (`workbench list problems`).")],
    formalism: Annotated[str, typer.Option("-f", "--formalism", help="Formalism name.")],
    integrator: Annotated[str, typer.Option("-i", "--integrator", help="Integrator name.")],
    rtol: Annotated[float, typer.Option("--rtol", help="Relative tolerance.")] = 1e-6,
    atol: Annotated[
        float | None, typer.Option("--atol", help="Absolute tolerance (default rtol * 1e-3).")
    ] = None,
    option: Annotated[
        list[str] | None,
        typer.Option("-o", "--option", help="[problem.|formalism.|integrator.]NAME=VALUE"),
    ] = None,
    out: Annotated[
        str | None, typer.Option("--out", help="Also store the run in this results directory.")
    ] = None,
) -> None:
    """Run one problem with one formalism and integrator and print its metrics."""
    from pathlib import Path

    from workbench.errors import ConfigError
    from workbench.runs import store
    from workbench.runs.execute import RunSpec, execute_run, normalized_spec

    if not rtol > 0 or (atol is not None and not atol > 0):
        raise ConfigError(f"tolerances must be > 0 (rtol={rtol}, atol={atol})")
    classes = {
        "problem": registry.get_problem(problem),
        "formalism": registry.get_formalism(formalism),
        "integrator": registry.get_integrator(integrator),
    }
    options = _run_options(option or [])
    _assign_options(options, classes)
    spec = normalized_spec(
        RunSpec(
            problem,
            formalism,
            integrator,
            rtol,
            atol if atol else rtol * 1e-3,
            options["problem"],
            options["formalism"],
            options["integrator"],
        )
    )
    reference_dir = Path(out) / "references" if out else None
    result = execute_run(spec, reference_dir=reference_dir)
    if out:
        store.write_run(Path(out), result.row, result.series)
    table = Table(title=f"run {spec.run_id}", title_justify="left", show_header=False)
    table.add_column("metric", no_wrap=True)
    table.add_column("value")
    for name, value in result.row.items():
        table.add_row(name, _cell(value))
    console().print(table)


def _cell(value: Any) -> str:
    if isinstance(value, float):
        return "" if value != value else f"{value:.4g}"
    return "" if value is None else str(value)


@app.command()
def sweep(
    spec: Annotated[
        str | None, typer.Argument(help="Sweep specification (TOML); default: the default sweep.")
    ] = None,
    jobs: Annotated[int | None, typer.Option("--jobs", "-j", help="Worker processes.")] = None,
    scheduler: Annotated[
        str | None, typer.Option("--scheduler", help="Dask scheduler address (tcp://host:port).")
    ] = None,
    out: Annotated[str | None, typer.Option("--out", "-o", help="Output directory.")] = None,
    time_limit: Annotated[
        float | None, typer.Option("--time-limit", help="Seconds per run before it is killed.")
    ] = None,
) -> None:
    """Run a sweep (problems x formalisms x integrators x tolerances); resumes if interrupted."""
    from workbench.errors import ConfigError
    from workbench.runs.sweep import load_spec, run_sweep

    if jobs is not None and jobs < 1:
        raise ConfigError(f"--jobs must be >= 1, not {jobs}")
    if time_limit is not None and not time_limit > 0:
        raise ConfigError(f"--time-limit must be > 0 s, not {time_limit}")
    loaded = load_spec(spec)
    summary = run_sweep(loaded, jobs=jobs, out=out, time_limit=time_limit, scheduler=scheduler)
    counts = ", ".join(f"{summary.counts[s]} {s}" for s in ("ok", "failed", "skipped", "timeout"))
    typer.echo(
        f"{summary.total} runs in {summary.seconds:.1f} s ({counts}); "
        f"{summary.already_done} already done"
    )
    typer.echo(f"results: {summary.out}/ (workbench results {summary.out})")
    from workbench.report import report_directory

    index = report_directory(summary.out, command=" ".join(["workbench", *sys.argv[1:]]))
    typer.echo(f"report: {index}")
    if summary.recording is not None:
        typer.echo(f"recording: {summary.recording} (workbench view {summary.recording})")


RESULT_COLUMNS = [
    "problem",
    "formalism",
    "formalism_options",
    "integrator",
    "rtol",
    "status",
    "wall_s",
    "n_rhs",
    "err_end",
    "scd",
    "drift_pos_max",
    "energy_err_max",
    "message",
]


@app.command()
def results(
    path: Annotated[str, typer.Argument(help="A results directory or a results.parquet file.")],
) -> None:
    """Print the result rows of a sweep as a table."""
    import warnings

    from workbench.runs.store import load_results

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        frame = load_results(path)
    for warning in caught:
        typer.echo(f"warning: {warning.message}", err=True)
    table = Table(title=f"{len(frame)} runs in {path}", title_justify="left")
    for column in RESULT_COLUMNS:
        table.add_column(column.replace("_options", " opts"), overflow="fold")
    for row in frame[RESULT_COLUMNS].itertuples(index=False):
        cells = [_cell(v) for v in row]
        cells[-1] = cells[-1][:80]
        table.add_row(*cells)
    out = console()
    out.width = max(out.width, 180)  # a wide table: let a narrow terminal wrap it
    out.print(table)


# -- plugin authors -------------------------------------------------------------------
@app.command("new")
def new(
    kind: Annotated[str, typer.Argument(help="formalism, integrator or problem.")],
    name: Annotated[str, typer.Argument(help="The plugin name, e.g. my-formalism.")],
    package: Annotated[
        str | None,
        typer.Option("--package", help="Write a separate installable package into this directory."),
    ] = None,
    force: Annotated[bool, typer.Option("--force", help="Overwrite existing files.")] = False,
) -> None:
    """Write a ready-to-edit plugin: module, conformance test (and with --package, a package)."""
    from workbench.plugin.scaffold import scaffold

    written = scaffold(describe_kind(kind), name, package=package, force=force)
    for path in written.files:
        typer.echo(f"wrote {path}")
    typer.echo("next: " + "\n      ".join(written.next_steps))


# -- reports --------------------------------------------------------------------------
@app.command("report")
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
    import warnings

    from workbench.report import report_directory

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        index = report_directory(results_path, out)
    for warning in caught:
        typer.echo(f"warning: {warning.message}", err=True)
    typer.echo(f"report: {index}")


@app.command("view")
def view(
    path: Annotated[
        str,
        typer.Argument(help="A Rerun recording (.rrd) or a directory with recording.rrd."),
    ] = "recording.rrd",
) -> None:
    """Open a Rerun recording in the Rerun viewer (or say how, when there is no display)."""
    import os
    import shlex
    import shutil
    import subprocess
    from pathlib import Path

    from workbench.errors import ConfigError
    from workbench.recording import RECORDING_FILE

    recording = Path(path)
    if recording.is_dir():
        recording = recording / RECORDING_FILE
    if not recording.is_file():
        raise ConfigError(
            f"no recording at {recording}: give a .rrd file written by RerunSink.save "
            "(e.g. the recording.rrd of a sweep's output directory)"
        )
    executable = shutil.which("rerun")
    viewer = [executable] if executable else [sys.executable, "-m", "rerun"]
    if not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        typer.echo(
            f"no display (DISPLAY / WAYLAND_DISPLAY unset); to look at {recording}:\n"
            f"  on a machine with a display:  rerun {shlex.quote(str(recording))}\n"
            f"  in a browser:  rerun --serve-web {shlex.quote(str(recording))}  "
            "(then open the printed URL; forward its ports over ssh if remote)"
        )
        return
    try:
        subprocess.Popen([*viewer, str(recording)], start_new_session=True)
    except OSError as error:
        raise ConfigError(
            f"cannot start the Rerun viewer ({error}); install rerun-sdk or run "
            f"`rerun {shlex.quote(str(recording))}` yourself"
        ) from None
    typer.echo(f"opened {recording} in the Rerun viewer")


# -- stored references ----------------------------------------------------------------
@app.command("reference")
def reference_command(
    problem: Annotated[str | None, typer.Argument(help="Problem name (or --all).")] = None,
    rtol: Annotated[
        float, typer.Option("--rtol", help="Relative tolerance of both pipelines (atol rtol/10).")
    ] = 1e-11,
    samples: Annotated[
        int | None, typer.Option("--samples", help="Sample times (default: the problem's).")
    ] = None,
    out: Annotated[
        str | None,
        typer.Option("--out", help="Directory (default: references/ beside the problem module)."),
    ] = None,
    every: Annotated[
        bool, typer.Option("--all", help="Every problem without an analytic reference.")
    ] = False,
) -> None:
    """Compute body poses with two independent pipelines; if they agree, store them."""
    from workbench.runs.references import run_command

    run_command(console(), problem, every, rtol, samples, out)


def main() -> None:
    """Console-script entry point (``workbench``)."""
    try:
        app()
    except WorkbenchError as error:  # raised outside a command (e.g. by a callback)
        sys.exit(fail(error).exit_code)


if __name__ == "__main__":
    main()
