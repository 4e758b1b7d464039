"""Commands that run: ``workbench run``, ``sweep``, ``results`` and ``reference``."""

from __future__ import annotations

import shlex
import sys
from typing import Annotated, Any

import typer
from rich.table import Table

from workbench.cli.app import (
    CostOption,
    app,
    console,
    option_value,
    refuse_short_out,
    warnings_on_stderr,
)
from workbench.cli.plugin_flags import NoLocalPluginsOption, PluginsOption, plugins_from_flags
from workbench.cli.robot_files import ALLOW_ROOT_OPTION, PACKAGE_PATH_OPTION
from workbench.execution.timing import (
    DEFAULT_REPEAT_BUDGET,
    DEFAULT_REPEATS,
    Timing,
    check_budget,
    check_repeats,
)
from workbench.plugin import registry
from workbench.plugin.options import option_fields, unknown_option


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
        if option in parsed[kind]:  # the last one silently won: not a grid (a sweep's is)
            raise ConfigError(
                f"-o {name.strip()}: given twice; a run takes one value of each option (a "
                "sweep specification takes a list: its grid)"
            )
        parsed[kind][option] = option_value(value.strip())
    return parsed


def _assign_options(parsed: dict[str, dict[str, Any]], classes: dict[str, type]) -> None:
    from workbench.errors import ConfigError

    for option, value in parsed.pop("").items():
        for kind in ("formalism", "integrator", "problem"):
            names = [n for n, _, _ in option_fields(classes[kind].Options)]
            if option in names:
                if option in parsed[kind]:  # -o index=1 -o formalism.index=2
                    raise ConfigError(
                        f"-o {option}: given twice (also as {kind}.{option}); a run takes "
                        "one value of each option"
                    )
                parsed[kind][option] = value
                break
        else:
            raise ConfigError(
                f"-o {option}: {unknown_option(option, classes)}; see `workbench describe NAME`"
            )


@app.command()
def run(
    ctx: typer.Context,
    problem: Annotated[
        str,
        typer.Argument(
            help="Problem name (`workbench list problems`), a .urdf/.xml file, or "
            "MODULE_OR_FILE:Class (e.g. my_problem.py:MyProblem)."
        ),
    ],
    formalism: Annotated[
        str, typer.Option("-f", "--formalism", help="Formalism name (or MODULE_OR_FILE:Class).")
    ],
    integrator: Annotated[
        str, typer.Option("-i", "--integrator", help="Integrator name (or MODULE_OR_FILE:Class).")
    ],
    rtol: Annotated[
        float, typer.Option("--rtol", help="Relative tolerance (0 < rtol < 1).")
    ] = 1e-6,
    atol: Annotated[
        float | None, typer.Option("--atol", help="Absolute tolerance (default rtol * 1e-3).")
    ] = None,
    option: Annotated[
        list[str] | None,
        typer.Option(
            "-o",
            "--option",
            help="An option NAME=VALUE of the formalism, integrator or problem (the first that "
            "has NAME; or formalism.NAME, integrator.NAME, problem.NAME), e.g. -o index=1.",
        ),
    ] = None,
    out: Annotated[
        str | None, typer.Option("--out", help="Also store the run in this results directory.")
    ] = None,
    time_limit: Annotated[
        float,
        typer.Option("--time-limit", help="Seconds before the run is killed (a timeout row)."),
    ] = 120.0,
    repeats: Annotated[
        int,
        typer.Option("--repeats", help="Most timed samples of the integration (median kept)."),
    ] = DEFAULT_REPEATS,
    repeat_budget: Annotated[
        float,
        typer.Option(
            "--repeat-budget",
            help="CPU seconds of integration the samples may take together.",
        ),
    ] = DEFAULT_REPEAT_BUDGET,
    package_path: Annotated[list[str] | None, PACKAGE_PATH_OPTION] = None,
    allow_root: Annotated[list[str] | None, ALLOW_ROOT_OPTION] = None,
    wait: Annotated[
        bool, typer.Option("--wait", help="If --out is in use by another command, wait for it.")
    ] = False,
    plugins: PluginsOption = None,
    no_local_plugins: NoLocalPluginsOption = False,
) -> None:
    """Run one problem with one formalism and integrator and print its metrics.

    The checks are a sweep specification's (tolerances, typed options, step counts); the
    run executes in a child process that is killed at --time-limit, as a sweep's are.
    """
    import os
    from pathlib import Path

    from workbench.errors import ConfigError
    from workbench.execution.execute import RunSpec, normalized_spec
    from workbench.execution.run_log import store_log
    from workbench.files import make_dirs
    from workbench.runs import store
    from workbench.runs.dask_pool import run_in_subprocess

    if not (0 < time_limit < float("inf")):
        raise ConfigError(f"--time-limit must be a finite number of seconds > 0, not {time_limit}")
    timing = Timing(
        check_repeats(repeats, "--repeats"), check_budget(repeat_budget, "--repeat-budget")
    )
    from workbench.plugin.robot_problem import robot_file_problem

    loaded, (problem, formalism, integrator) = plugins_from_flags(
        plugins, no_local_plugins, problem, formalism, integrator
    )
    problem, option = robot_file_problem(problem, option or [], package_path, allow_root)
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
            atol if atol is not None else rtol * 1e-3,
            options["problem"],
            options["formalism"],
            options["integrator"],
        )
    )
    reference_dir = ""
    if out:  # one command at a time on OUT (held until the command ends), no link in it
        hold_out_lock(ctx, out, wait)
        make_dirs(Path(out) / "references", Path(out))
        reference_dir = str((Path(out) / "references").resolve())
    # the child imports the plugin modules loaded here (a local one from its file), then
    # the modules that registered these plugins (built-in or not)
    from workbench.plugin.local_modules import imported_from_file

    modules = [module.text() for module in loaded] + sorted(
        {c.__module__ for c in classes.values() if not imported_from_file(c.__module__)}
    )
    paths = [str(Path(p).resolve()) if p else os.getcwd() for p in sys.path]
    row, series = run_in_subprocess(
        spec.to_dict(), time_limit, modules, reference_dir, paths, timing.to_dict()
    )
    store_log(Path(out) if out else None, row)
    if out:
        store.write_run(Path(out), row, series)
    table = Table(title=f"run {spec.run_id}", title_justify="left", show_header=False)
    table.add_column("metric", no_wrap=True)
    table.add_column("value")
    from workbench.outputs.results_table import UNREPORTED_COUNTS

    for name, value in row.items():
        unreported = name in UNREPORTED_COUNTS and value == -1  # not a count of -1
        table.add_row(name, "not reported by the integrator" if unreported else _cell(value))
    console().print(table)
    if row.get("status") != "ok":  # the table says what was measured; the exit status, that
        typer.echo(f"error: run {row.get('status')}: {row.get('message', '')}", err=True)
        raise typer.Exit(EXIT_RUN_NOT_OK)


EXIT_RUN_NOT_OK = 1  # the run was skipped, failed or timed out (2 stays bad input)


def hold_out_lock(ctx: typer.Context, out: Any, wait: bool) -> None:
    """Hold the lock of the output directory ``out`` until the command of ``ctx`` ends
    (:func:`workbench.runs.out_lock.out_lock`; click releases it however the command ends)."""
    from workbench.runs.out_lock import out_lock

    ctx.with_resource(out_lock(out, wait=wait, say=typer.echo))


def _cell(value: Any) -> str:
    if isinstance(value, float):
        return "" if value != value else f"{value:.4g}"
    return "" if value is None else str(value)


@app.command()
def sweep(
    ctx: typer.Context,
    spec: Annotated[
        str | None,
        typer.Argument(
            help="Sweep specification (TOML file) or suite name: a file of "
            "workbench/runs/suites/ (quick, full, iftomm, ivp, nonsmooth; an unknown name "
            "lists them); default: quick, a first look in about a minute.",
        ),
    ] = None,
    jobs: Annotated[int | None, typer.Option("--jobs", "-j", help="Worker processes.")] = None,
    scheduler: Annotated[
        str | None, typer.Option("--scheduler", help="Dask scheduler address (tcp://host:port).")
    ] = None,
    out: Annotated[
        str | None,
        typer.Option("--out", help="Output directory (default: the specification's out)."),
    ] = None,
    old_out: Annotated[str | None, typer.Option("-o", hidden=True)] = None,
    time_limit: Annotated[
        float | None,
        typer.Option(
            "--time-limit",
            help="Seconds per run before it is killed (default: the specification's "
            "time_limit, else 120).",
        ),
    ] = None,
    rerun: Annotated[
        str | None,
        typer.Option(
            "--rerun",
            help="Redo done runs of these kinds: a comma list of failed, timeout, skipped, "
            "stale (made by other code).",
        ),
    ] = None,
    fresh: Annotated[
        bool,
        typer.Option(
            "--fresh", help="Redo every run (a row is replaced only when its run finishes)."
        ),
    ] = False,
    repeats: Annotated[
        int | None,
        typer.Option("--repeats", help="Most timed samples of each integration (median kept)."),
    ] = None,
    repeat_budget: Annotated[
        float | None,
        typer.Option(
            "--repeat-budget",
            help="CPU seconds of integration a run's samples may take together.",
        ),
    ] = None,
    retime: Annotated[
        int | None,
        typer.Option(
            "--retime",
            help="Times each close call (pairs within 3x of a cheapest) is timed again after "
            "the runs, at moments 2 s apart, so that a second sweep names the same winner "
            "(default 5; 0: not at all).",
        ),
    ] = None,
    wait: Annotated[
        bool,
        typer.Option("--wait", help="If the output directory is in use, wait for it to be free."),
    ] = False,
    no_report: Annotated[
        bool,
        typer.Option(
            "--no-report",
            help="Write the rows, series and recording but no report (a campaign run in "
            "parts, a batch job): `workbench report OUT` writes it later.",
        ),
    ] = False,
    no_recording: Annotated[
        bool,
        typer.Option(
            "--no-recording",
            help="Write no Rerun recording (many small runs: it costs a tiny run about as "
            "much as its rows and series): `workbench record OUT` records runs later.",
        ),
    ] = False,
    plugins: PluginsOption = None,
    no_local_plugins: NoLocalPluginsOption = False,
) -> None:
    """Run a sweep (problems x formalisms x integrators x tolerances); resumes if interrupted.

    Without SPEC: the quick suite, a first look in about a minute; `workbench sweep full`
    is the full comparison. Before the first run it prints the planned runs and an
    estimate of the time from measured costs (docs/suites.md).

    The specification's `plugins` and --plugins are code: a local module is imported from
    its file once the rest of the specification is valid, said on stderr, and refused
    under --no-local-plugins (or WORKBENCH_NO_LOCAL_PLUGINS=1).

    Exit status 1 if some runs could not be completed (their worker was killed from
    outside or lost): they have no row, and running the same command again redoes them.
    """
    from workbench.errors import ConfigError
    from workbench.runs import store
    from workbench.runs.dask_pool import CLIENT_LOG
    from workbench.runs.resume import parse_rerun
    from workbench.runs.sweep import load_spec, run_sweep
    from workbench.runs.sweep_spec import FULL_SUITE

    refuse_short_out(old_out, "sweep")
    if jobs is not None and jobs < 1:
        raise ConfigError(f"--jobs must be >= 1, not {jobs}")
    if time_limit is not None and not time_limit > 0:
        raise ConfigError(f"--time-limit must be > 0 s, not {time_limit}")
    if scheduler is not None:  # (an empty one too: it ran on the local pool)
        from workbench.runs.dask_pool import check_scheduler_address

        check_scheduler_address(scheduler)  # before OUT is made
    from workbench.files import usable_cache_dir

    usable_cache_dir()  # also before OUT is made
    kinds = parse_rerun(rerun)
    # None: unless WORKBENCH_NO_LOCAL_PLUGINS is set
    with warnings_on_stderr():  # "all" leaving out a broken plugin
        loaded = load_spec(spec, plugins or [], False if no_local_plugins else None)
    _say_on_interrupt(loaded, out)
    hold_out_lock(ctx, out or loaded.out, wait)  # the report below too
    from workbench.outputs.recording import SweepRecorder
    from workbench.outputs.report.close_calls import close_calls

    summary = run_sweep(
        loaded,
        jobs=jobs,
        out=out,
        time_limit=time_limit,
        scheduler=scheduler,
        recorder=None if no_recording else SweepRecorder,
        rerun=kinds,
        fresh=fresh,
        say=typer.echo,
        repeats=repeats,
        repeat_budget=repeat_budget,
        close_calls=close_calls,
        retime=retime,
    )
    shown = ("ok", "failed", "skipped", "timeout") + (("unfinished",) if summary.unfinished else ())
    counts = ", ".join(f"{summary.counts[s]} {s}" for s in shown)
    typer.echo(
        f"{summary.total} runs in {summary.seconds:.1f} s ({counts}); "
        f"{summary.already_done} already done"
        + (
            f", {len(summary.stale)} of them stale (--rerun stale redoes them)"
            if summary.stale
            else ""
        )
    )
    typer.echo(f"results: {summary.out}/ (workbench results {summary.out})")
    if summary.counts["failed"] or summary.counts["timeout"]:
        typer.echo(
            f"why runs failed or timed out: workbench results {shlex.quote(str(summary.out))} "
            '--by run --where "status!=ok" --where "status!=skipped" '
            "--columns problem,pair,rtol,status,message"
        )
    from workbench.outputs.report import current_report, kept_cost, report_directory

    kept = " (unchanged: made from the same rows)"
    cost = kept_cost(summary.out)  # `workbench report --cost` chose it before
    measure = f" (cost measure {cost}, as `workbench report --cost` chose)" if cost else ""
    if summary.unfinished and not store.completed_run_ids(summary.out):
        typer.echo("report: none (no run has a row yet)")
    elif index := current_report(summary.out, stale=summary.stale, cost=cost):
        typer.echo(f"report: {index}{kept}")
    elif no_report:
        older = summary.out / "report" / "index.html"
        typer.echo(
            "report: not written (--no-report"
            + (f"; {older} is not current: other rows or code made it" if older.is_file() else "")
            + f"); `workbench report {summary.out}{f' --cost {cost}' if cost else ''}` writes it"
        )
    else:
        index = _sweep_report(summary, report_directory, cost)
        typer.echo(f"report: {index}{measure}")
    if summary.recording is not None:
        same = "unchanged: made from the same runs; " * (
            summary.recording.name in summary.unchanged
        )
        typer.echo(f"recording: {summary.recording} ({same}workbench view {summary.recording})")
    elif no_recording:
        from workbench.outputs.recording import RECORDING_FILE

        older = summary.out / RECORDING_FILE
        typer.echo(
            "recording: none written (--no-recording"
            + (f"; {older} holds only runs recorded before" if older.is_file() else "")
            + f"); `workbench record {summary.out} --where ...` records the runs chosen"
        )
    if loaded.suite != FULL_SUITE:
        typer.echo(
            f"full comparison: workbench sweep {FULL_SUITE} (every problem, formalism and "
            "integrator family; it says how long it will take before it starts)"
        )
    if summary.unfinished:
        first, why = next(iter(summary.unfinished.items()))
        again = " ".join(["workbench", *_without_rerun(sys.argv[1:])])
        named = list(summary.unfinished)[:5]
        more = len(summary.unfinished) - len(named)
        runs = ", ".join(named) + (f" and {more} more" if more else "")
        typer.echo(
            f"{len(summary.unfinished)} run(s) could not be completed, not by their own fault "
            f"(runs {runs}; e.g. run {first}: {why}); they have no row: resume with `{again}`"
            + (f" (Dask's own messages: {summary.out / 'logs' / CLIENT_LOG})" if scheduler else ""),
            err=True,
        )
        raise typer.Exit(1)


@app.command()
def record(
    ctx: typer.Context,
    out: Annotated[str, typer.Argument(help="A sweep's output directory.")],
    where: Annotated[
        list[str] | None,
        typer.Option(
            "--where", "-w", help="Record the runs with COLUMN OP VALUE, e.g. status=ok (repeat)."
        ),
    ] = None,
    jobs: Annotated[int, typer.Option("--jobs", "-j", help="Worker processes.")] = 2,
    time_limit: Annotated[
        float, typer.Option("--time-limit", help="Seconds per run before it is killed.")
    ] = 300.0,
    wait: Annotated[
        bool,
        typer.Option("--wait", help="If the output directory is in use, wait for it to be free."),
    ] = False,
    allow_root: Annotated[
        list[str] | None,
        typer.Option(
            "--allow-root",
            help="A folder outside OUT whose robot files the runs may read (repeatable; "
            "only for results you trust).",
        ),
    ] = None,
    plugins: PluginsOption = None,
    no_local_plugins: NoLocalPluginsOption = False,
) -> None:
    """Record done runs of a sweep in OUT/recording.rrd by running them again (rows kept).

    For a sweep run with --no-recording, or by the Python API (which writes none): the
    runs chosen with --where (all without it) whose status is ok and whose row is not
    stale are run again in worker processes, and their recordings merged into the
    sweep's (a run recorded before is replaced). A results folder is data: a local plugin
    module the runs need is named with --plugins, and a robot file outside OUT that they
    read with --allow-root (its folder).
    """
    from pathlib import Path

    from workbench.errors import ConfigError
    from workbench.outputs.recording import SweepRecorder
    from workbench.outputs.results_table import rows_where
    from workbench.runs.record import record_runs

    if not time_limit > 0:
        raise ConfigError(f"--time-limit must be > 0 s, not {time_limit}")
    if not Path(out).is_dir():  # (before its lock would make it)
        raise ConfigError(f"no output directory {out}: give the OUT of a sweep")

    def choose(frame: Any) -> Any:
        kept = rows_where(frame, where or [])
        if kept.empty:
            raise ConfigError(
                f"no run of the {len(frame)} in {out} meets --where "
                f"{' --where '.join(where or [])}: `workbench results {out} --by run` lists them"
            )
        return kept

    plugins_from_flags(plugins, no_local_plugins)  # refused or imported here first
    hold_out_lock(ctx, out, wait)
    summary = record_runs(
        out, SweepRecorder, choose, jobs, plugins or [], time_limit, say=typer.echo,
        allow_roots=allow_root or [],
    )  # fmt: skip
    left = "; ".join(f"{count} left out: {why}" for why, count in summary.left_out.items())
    if summary.failed:
        typer.echo(
            f"{len(summary.failed)} run(s) failed when run again (e.g. {summary.failed[0]}): "
            "not recorded",
            err=True,
        )
    if not summary.recorded:  # (a recording made before may be there, as it was)
        kept = f"; {summary.recording} as it was" if summary.recording is not None else ""
        typer.echo("no run recorded" + (f" ({left})" if left else "") + kept)
        raise typer.Exit(1)
    typer.echo(
        f"{summary.recorded} run(s) recorded" + (f" ({left})" if left else "")
        + f"; recording: {summary.recording} (workbench view {summary.recording})"
    )  # fmt: skip
    if summary.failed:
        raise typer.Exit(1)


def _sweep_report(summary: Any, report_directory: Any, cost: str | None) -> Any:
    """The sweep's report (its warnings one line each on stderr); a report that cannot be
    finished (e.g. a figure worker killed twice) is one line and exit 1: the rows are
    kept and ``workbench report OUT`` rebuilds it."""
    from workbench.errors import WorkbenchError, one_line

    with warnings_on_stderr():
        try:
            index = report_directory(
                summary.out,
                command=" ".join(["workbench", *sys.argv[1:]]),
                stale=summary.stale,
                cost=cost,
                rows=summary.rows,  # read once by the sweep's consolidation
            )
        except (WorkbenchError, OSError):
            raise
        except Exception as error:  # noqa: BLE001 - the rows stand; the report is a view
            typer.echo(
                f"error: the report of {summary.out} is unfinished ({one_line(error)}); "
                "the rows are kept: rebuild it with "
                f"`workbench report {summary.out}`",
                err=True,
            )
            raise typer.Exit(1) from None
    return index


def _without_rerun(arguments: list[str]) -> list[str]:
    """The command line without --fresh and --rerun (a resume redoes unfinished runs)."""
    kept, skip = [], False
    for argument in arguments:
        if skip:
            skip = False
        elif argument == "--rerun":
            skip = True
        elif argument != "--fresh" and not argument.startswith("--rerun="):
            kept.append(argument)
    return kept


def _say_on_interrupt(loaded: Any, out: str | None) -> None:
    """On Ctrl-C: how many runs of this sweep are kept in its directory, and how to resume."""
    from pathlib import Path

    from workbench.cli.app import on_interrupt
    from workbench.runs import store

    out_dir = Path(out) if out else Path(loaded.out)
    wanted = {spec.run_id for spec in loaded.runs}
    command = " ".join(["workbench", *sys.argv[1:]])

    def describe() -> str:
        kept = len(wanted & store.completed_run_ids(out_dir))  # whole rows only
        return (
            f"{kept} of {len(wanted)} runs are kept in {out_dir}; run `{command}` again to resume"
        )

    on_interrupt(describe)


@app.command()
def results(
    path: Annotated[str, typer.Argument(help="A results directory or a results.parquet file.")],
    by: Annotated[
        str, typer.Option("--by", help="A line a problem (default), a problem x pair, or a run.")
    ] = "problem",
    columns: Annotated[
        str | None,
        typer.Option("--columns", "-c", help="Comma-separated columns to show, in order."),
    ] = None,
    where: Annotated[
        list[str] | None,
        typer.Option("--where", "-w", help="Keep rows with COLUMN OP VALUE, e.g. scd>=6 (repeat)."),
    ] = None,
    sort: Annotated[
        str | None,
        typer.Option("--sort", "-s", help="Comma-separated columns to sort by; -name descends."),
    ] = None,
    fmt: Annotated[
        str, typer.Option("--format", "-f", help="table, csv, markdown or latex.")
    ] = "table",
    cost: CostOption = None,
) -> None:
    """Print a sweep's results: a line a problem (or --by pair, --by run), filtered and sorted."""
    from pathlib import Path

    from workbench.errors import ConfigError
    from workbench.outputs.report.analysis import (
        coverage_heading,
        coverage_notice,
        prepare_results,
    )
    from workbench.outputs.report.cost import resolve_cost
    from workbench.outputs.report.tables import table_cells
    from workbench.outputs.results_table import (
        FORMATS,
        caption,
        legend,
        render,
        results_table,
        unmatched,
        with_option_columns,
    )
    from workbench.runs.store import load_plan, load_results

    if fmt not in FORMATS:
        raise ConfigError(f"--format {fmt!r}: choose one of {', '.join(FORMATS)}")
    with warnings_on_stderr():
        frame = load_results(path)
    if cost is None:  # the measure of the folder's report, so that the two agree
        from workbench.outputs.report import kept_cost

        cost = kept_cost(path) if Path(path).is_dir() else None
        if cost is not None:
            typer.echo(f"cost measure: {cost}, as the folder's report (--cost to choose)",
                       err=True)  # fmt: skip
    # the report's red notice (templates/report.html.j2): a verdict on part of the
    # planned sweep (rows deleted, the sweep interrupted) says so here too
    folder = Path(path) if Path(path).is_dir() else Path(path).parent
    plan = load_plan(folder)
    notice = coverage_notice(frame, plan)
    if notice:
        typer.secho(f"{coverage_heading(frame, plan)}: {notice}.", fg="red", err=True)

    def split(text: str | None) -> list[str]:
        return [item.strip() for item in (text or "").split(",") if item.strip()]

    table = results_table(frame, by=by, columns=split(columns), where=where or [],
                          sort=split(sort), cost=cost)  # fmt: skip
    if where and len(table) == 0:  # an empty table says nothing of why: a misspelled value?
        why = unmatched(with_option_columns(prepare_results(frame)), where)
        typer.echo(
            f"note: no run of the {len(frame)} in {path} meets --where "
            + " --where ".join(where) + ("; " + "; ".join(why) if why else ""),
            err=True,
        )  # fmt: skip
    statement = resolve_cost(prepare_results(frame), cost).statement()
    # a table for a paper or a page does not name this machine's folder
    title = caption(table, len(frame), by, path if fmt == "table" else "", statement)
    if fmt in ("markdown", "latex") and len(table) == 0:  # an empty tabular{} breaks LaTeX
        typer.echo(f"note: no line to write as {fmt}: the table is empty", err=True)
        return
    if fmt != "table":
        typer.echo(render(table, fmt, title), nl=False)
        return
    header, cells = table_cells(table)
    shown = Table(title=title, title_justify="left", caption=legend(table) or None,
                  caption_justify="left")  # fmt: skip
    for name in header:  # a problem's name whole: what a line is about (a narrow
        shown.add_column(name, overflow="fold", no_wrap=name == "problem")  # cell split it)
    for line in cells:
        shown.add_row(*line)
    out = console()
    out.width = max(out.width, 160)  # a wide table: let a narrow terminal wrap it
    out.print(shown)
    if by != "run":
        others = " or ".join(f"--by {other}" for other in ("pair", "run") if other != by)
        typer.echo(
            f"more: {others}; choose with --where, --sort, --columns; --format csv|markdown|latex"
        )


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
    _store_references(console(), problem, every, rtol, samples, out)


def _store_references(
    out: Any,
    problem: str | None,
    every: bool,
    rtol: float,
    samples: int | None,
    directory: str | None,
) -> list[Any]:
    """``workbench reference``: compute, check and write (the paths written); a rich
    progress bar on stderr and a table of the agreement on ``out`` (a rich Console). Raises
    ReferenceDisagreement at the end if any problem's pipelines disagreed (the others are
    written)."""
    from workbench.execution.references import (
        ReferenceDisagreement,
        compute_reference,
        reference_names,
        write_reference,
    )
    from workbench.runs.progress import progress_bar

    names = reference_names(problem, every)
    table = Table(title="stored references", title_justify="left")
    for column in ("problem", "A (stored)", "B", "agreement / L", "at", "seconds", "file"):
        table.add_column(column, overflow="fold")
    written, failures = [], []
    with progress_bar("references", 2 * len(names)) as bar:  # two pipelines a problem
        for name in names:
            try:
                stored = compute_reference(name, rtol, samples, progress=bar.step)
            except ReferenceDisagreement as error:
                failures.append(str(error))
                table.add_row(name, "", "", "disagree", "", "", str(error))
                continue
            path = write_reference(stored, directory)
            written.append(path)
            agreed, (first, second) = stored.metadata["agreement"], stored.metadata["pipelines"]
            table.add_row(
                name,
                first["label"],
                second["label"],
                f"{agreed['relative']:.2g}",
                f"t={agreed['at_time_s']:g} s {agreed['body']}",
                f"{sum(p['build_s'] + p['integrate_s'] for p in (first, second)):.1f}",
                str(path),
            )
    out.width = max(out.width, 160)  # a wide table: let a narrow terminal wrap it
    out.print(table)
    if failures:
        raise ReferenceDisagreement(" | ".join(failures))
    return written
