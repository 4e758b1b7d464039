"""Commands that show results: ``workbench report`` and ``view``."""

from __future__ import annotations

import os
import sys
from typing import Annotated, Any

import typer

from workbench.cli.app import app, refuse_short_out


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
        typer.Option("--out", help="Report directory (default: RESULTS/report)."),
    ] = None,
    old_out: Annotated[str | None, typer.Option("-o", hidden=True)] = None,
    cost: Annotated[
        str | None,
        typer.Option(
            "--cost",
            help="Cost measure of the diagrams, tables and recommendation: integrate_cpu "
            "(default), integrate_wall or n_rhs.",
        ),
    ] = None,
) -> None:
    """Write an HTML report (figures, tables as CSV/Markdown/LaTeX) of a results directory."""
    import warnings

    from workbench.cli.app import on_interrupt
    from workbench.outputs.report import report_directory
    from workbench.outputs.report.cost import check_cost

    refuse_short_out(old_out, "report")
    check_cost(cost)  # before anything is read

    on_interrupt(
        lambda: f"the results in {results_path} are untouched, the report is unfinished; "
        f"run `workbench report {' '.join(sys.argv[2:]) or results_path}` again"
    )
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        index = report_directory(results_path, out, cost=cost)
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
    from workbench.outputs.recording import RECORDING_FILE

    recording = Path(path)
    if recording.is_dir():
        recording = recording / RECORDING_FILE
    if not recording.is_file():
        raise ConfigError(
            f"no recording at {recording}: give a .rrd file written by RerunSink.save "
            "(e.g. the recording.rrd of a sweep's output directory)"
        )
    viewer = rerun_command(shutil.which)
    rerun = shlex.join(viewer)
    if not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        typer.echo(
            f"no display (DISPLAY / WAYLAND_DISPLAY unset); to look at {recording}:\n"
            f"  on a machine with a display:  {rerun} {shlex.quote(str(recording))}\n"
            f"  in a browser:  {rerun} --serve-web {shlex.quote(str(recording))}  "
            "(then open the printed URL; forward its ports over ssh if remote)"
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
