"""Commands that show results: ``workbench report``, ``paper`` and ``view``."""

from __future__ import annotations

import os
import sys
from typing import Annotated, Any

import typer

from workbench.cli.app import CostOption, app, refuse_short_out

ResultsArgument = Annotated[
    str,
    typer.Argument(
        metavar="RESULTS",
        help="A results directory (the output of `workbench sweep`) or a results.parquet.",
    ),
]
WaitOption = Annotated[
    bool, typer.Option("--wait", help="If RESULTS is in use (a sweep), wait for it.")
]


def _write_report(
    ctx: typer.Context,
    results_path: str,
    out: str | None,
    cost: str | None,
    wait: bool,
    command: str,
    paper: Any = None,
) -> Any:
    """The report of RESULTS (under its lock when it is a folder: not while a sweep writes
    it, no link in it), its warnings one line each on stderr; returns its index.html."""
    from workbench.cli.app import on_interrupt, warnings_on_stderr
    from workbench.outputs.report import report_directory
    from workbench.outputs.report.cost import check_cost

    check_cost(cost)  # before anything is read
    if os.path.isdir(results_path):
        from workbench.cli.runs import hold_out_lock
        from workbench.outputs.report import kept_cost

        hold_out_lock(ctx, results_path, wait)
        if cost is None and (cost := kept_cost(results_path)):
            typer.echo(f"cost measure {cost}, as `workbench report --cost` chose before "
                       "(--cost integrate_cpu for the default)")  # fmt: skip
    on_interrupt(
        lambda: (
            f"the results in {results_path} are untouched, the {command} is unfinished; "
            f"run `workbench {command} {' '.join(sys.argv[2:]) or results_path}` again"
        )
    )
    with warnings_on_stderr():
        index = report_directory(results_path, out, cost=cost, paper=paper)
    typer.echo(f"report: {index}")
    return index


@app.command("report")
def report(
    ctx: typer.Context,
    results_path: ResultsArgument,
    out: Annotated[
        str | None,
        typer.Option("--out", help="Report directory (default: RESULTS/report)."),
    ] = None,
    old_out: Annotated[str | None, typer.Option("-o", hidden=True)] = None,
    cost: CostOption = None,
    wait: WaitOption = False,
) -> None:
    """Write an HTML report (figures, tables as CSV/Markdown/LaTeX) of a results directory."""
    refuse_short_out(old_out, "report")
    _write_report(ctx, results_path, out, cost, wait, "report")


LOCAL_ONLY = "127.0.0.1"
"""Where ``workbench view --web`` listens unless told otherwise (Rerun's own default is
0.0.0.0, every network the machine is on)."""


@app.command("paper")
def paper(
    ctx: typer.Context,
    results_path: ResultsArgument,
    out: Annotated[
        str | None,
        typer.Option("--out", help="Paper directory (default: RESULTS/paper)."),
    ] = None,
    cost: CostOption = None,
    wait: WaitOption = False,
) -> None:
    """Write a paper folder: main.tex with the report's LaTeX tables and PDF figures, which
    a document can also \\input and include one by one; compiled when pdflatex is there."""
    from pathlib import Path

    from workbench.outputs.report.paper import MAIN, compile_paper, pdflatex

    source = Path(results_path)
    folder = Path(out) if out else (source if source.is_dir() else source.parent) / "paper"
    _write_report(ctx, results_path, str(folder / "report"), cost, wait, "paper", folder)
    main = folder / MAIN
    if pdflatex() is None:
        typer.echo(f"paper: {main} (pdflatex not found; compile with `pdflatex {MAIN}` there)")
        return
    compiled = compile_paper(main)
    if compiled.pdf is None:
        typer.echo(f"paper: {main}; pdflatex failed:\n{compiled.log_tail}", err=True)
        raise typer.Exit(1)
    wide = f", widest overfull box {compiled.overfull_pt:g} pt" if compiled.overfull_pt else ""
    typer.echo(f"paper: {compiled.pdf} (from {main}{wide})")


@app.command("view")
def view(
    path: Annotated[
        str,
        typer.Argument(help="A Rerun recording (.rrd) or a directory with recording.rrd."),
    ] = "recording.rrd",
    web: Annotated[
        bool, typer.Option("--web", help="Serve the recording to a browser (rerun --serve-web).")
    ] = False,
    bind: Annotated[
        str,
        typer.Option(
            "--bind", help="With --web: the address to listen on (0.0.0.0: every network)."
        ),
    ] = LOCAL_ONLY,
    web_port: Annotated[int, typer.Option("--web-port", help="With --web: its HTTP port.")] = 9090,
    grpc_port: Annotated[
        int, typer.Option("--grpc-port", help="With --web: its gRPC port.")
    ] = 9876,
    run: Annotated[
        str | None,
        typer.Option("--run", help="Only this run (its id) of a sweep's recording."),
    ] = None,
) -> None:
    """Open a Rerun recording in the Rerun viewer (or say how, when there is no display).

    With --web it is served to a browser on this machine only (127.0.0.1) unless --bind
    names another address: a recording is data a network should not read by default.
    With --run, the run is copied out of the sweep's recording into a file of its own
    (in the workbench's cache folder), which is opened.
    """
    import os
    import shlex
    import shutil
    import subprocess
    from pathlib import Path

    from workbench.errors import ConfigError
    from workbench.outputs.recording import RECORDING_FILE

    recording = Path(path)
    if recording.is_dir():
        recording = recording / RECORDING_FILE
    if not recording.is_file():
        raise ConfigError(
            f"no recording at {recording}: give the recording.rrd of a sweep's output "
            "directory (or the directory); `workbench run --out` writes none, "
            "`workbench record OUT` makes one of a sweep run with --no-recording or from "
            "Python"
        )
    with recording.open("rb") as handle:
        if handle.read(3) != b"RRF":  # Rerun's files begin with RRF and a version digit
            raise ConfigError(
                f"{recording} is not a Rerun recording (.rrd): give the recording.rrd of "
                "a sweep's output directory (or the directory)"
            )
    if run is not None:
        recording = one_run_recording(recording, run)
    viewer = rerun_command(shutil.which)
    rerun = shlex.join(viewer)
    if web:
        served = [*viewer, "--serve-web", "--bind", bind, "--web-viewer-port", str(web_port)]
        typer.echo(f"serving {recording} to a browser on {bind} (Ctrl-C stops it)")
        subprocess.run([*served, "--port", str(grpc_port), str(recording)], check=False)
        return
    if not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        typer.echo(
            f"no display (DISPLAY / WAYLAND_DISPLAY unset); to look at {recording}:\n"
            f"  on a machine with a display:  {rerun} {shlex.quote(str(recording))}\n"
            f"  in a browser:  workbench view --web {shlex.quote(str(recording))}  "
            f"(= {rerun} --serve-web --bind {LOCAL_ONLY}; open the printed URL, forward its "
            "ports over ssh if remote)"
        )
        return
    try:
        subprocess.Popen([*viewer, str(recording)], start_new_session=True)
    except OSError as error:
        raise ConfigError(
            f"cannot start the Rerun viewer ({error}); install rerun-sdk or run "
            f"`{rerun} {shlex.quote(str(recording))}` yourself"
        ) from None
    typer.echo(f"opened {recording} in the Rerun viewer")


def one_run_recording(recording: Any, run_id: str) -> Any:
    """The file of one run (id ``run_id``) of the sweep whose recording is ``recording``,
    copied out of it into the cache folder; ConfigError naming what is missing."""
    from workbench.errors import ConfigError
    from workbench.files import user_cache_dir
    from workbench.outputs.recording import extract_run, run_path_of_row
    from workbench.runs import store

    row_file = store.row_path(recording.parent, run_id)
    row = store.read_row(row_file, settle=True) if row_file.is_file() else None
    if row is None:
        raise ConfigError(
            f"no run {run_id!r} in {recording.parent}: give a run id from "
            f"`workbench results {recording.parent} --by run -c run_id,problem,pair,rtol`"
        )
    target = user_cache_dir() / "views" / f"{run_id}.rrd"
    target.parent.mkdir(parents=True, exist_ok=True)
    try:
        return extract_run(recording, run_path_of_row(row), target)
    except ConfigError as error:  # a run of the sweep left out of its recording
        raise ConfigError(
            f"{error}; `workbench record {recording.parent} -w run_id={run_id}` records it"
        ) from None


def rerun_command(which: Any) -> list[str]:
    """The command that starts the Rerun viewer of this environment: the ``rerun`` script
    installed beside this Python (found without an activated venv), else one on PATH,
    else ``python -m rerun`` (rerun-sdk's module entry point)."""
    from pathlib import Path

    beside = Path(sys.executable).with_name("rerun")
    if beside.is_file() and os.access(beside, os.X_OK):
        return [str(beside)]
    found = which("rerun")
    return [found] if found else [sys.executable, "-m", "rerun"]
