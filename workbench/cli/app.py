"""The ``workbench`` command line (``workbench --help``; also ``python -m workbench``).

Adding a command is adding one function decorated with ``@app.command()`` in the module
of its group (``plugins``, ``runs``, ``outputs``; imported by ``workbench.cli``). A command
raises :class:`~workbench.errors.WorkbenchError` on bad input; :class:`WorkbenchGroup`
turns it into one line on stderr and exit code 2, so no command handles errors itself.
Tables go through :func:`console` (rich); plain messages through ``typer.echo``.
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Annotated, Any

import click
import typer
from rich.console import Console

from workbench import __version__
from workbench.errors import ConfigError, WorkbenchError, one_line, one_line_text

EXIT_BAD_INPUT = 2
EXIT_INTERRUPTED = 130  # 128 + SIGINT, as a shell reports a command ended by Ctrl-C
_ON_INTERRUPT: list[Callable[[], str]] = []  # the running command's: what was kept, how to resume

try:  # recent typer vendors click: its parser raises typer._click's exceptions
    from typer._click import exceptions as _typer_click
except ImportError:  # pragma: no cover - older typer uses click itself
    _typer_click = click.exceptions
USAGE_ERRORS = tuple({click.UsageError, _typer_click.UsageError})
NO_ARGS_IS_HELP = tuple(
    {
        m.NoArgsIsHelpError
        for m in (click.exceptions, _typer_click)
        if hasattr(m, "NoArgsIsHelpError")
    }
)


def fail(error: WorkbenchError) -> typer.Exit:
    """Print ``error`` as one line on stderr (its message, without the type: written for
    the user); the caller raises the returned Exit(2)."""
    typer.echo(f"error: {one_line(error, with_type=False)}", err=True)
    return typer.Exit(EXIT_BAD_INPUT)


def os_error_line(error: OSError) -> str:
    """An operating-system error (ENOSPC, EACCES, ENOTDIR, a refused connection...) as
    one line naming the path and what to do; results already written stay as they are."""
    reason = error.strerror or one_line(error, with_type=False)
    where = f": {error.filename}" if error.filename else ""
    if error.filename2:
        where += f" -> {error.filename2}"
    return (
        f"{reason}{where} (check the path, its permissions and the free space; "
        "results already written are kept and the command can be run again)"
    )


def _stdout_reader_gone() -> bool:
    """Whether standard output is a pipe whose reading end was closed (the write end
    then polls as an error)."""
    import select

    try:
        poller = select.poll()
        poller.register(sys.stdout.fileno(), select.POLLOUT)
        return any(events & select.POLLERR for _fd, events in poller.poll(0))
    except (AttributeError, OSError, ValueError):  # no poll here, or no file behind stdout
        return False


def on_interrupt(describe: Callable[[], str]) -> None:
    """Register what the current command says when Ctrl-C stops it: ``describe()`` names
    what was kept and how to resume (called then, so it can count what is on disk)."""
    _ON_INTERRUPT[:] = [describe]


def interrupted_line() -> str:
    """The one line printed on Ctrl-C: the command's own (see :func:`on_interrupt`) or a
    generic one."""
    for describe in _ON_INTERRUPT:
        try:
            return one_line_text(describe())
        except Exception:  # noqa: BLE001 - the interruption is the news, not this
            pass
    return "stopped by Ctrl-C; files already written are kept"


def reflowed(text: str) -> str:
    """A command's docstring with each paragraph on one line, so that the help wraps it
    to the terminal (Typer's rich help keeps the line breaks of every paragraph but the
    first); a paragraph that begins with Click's ``\\b`` keeps its lines."""
    import inspect

    paragraphs = inspect.cleandoc(text).split("\n\n")
    return "\n\n".join(
        p if p.startswith("\b") else " ".join(line.strip() for line in p.splitlines())
        for p in paragraphs
    )


OTHER_WORDS = {"plugins": "list", "ls": "list", "show": "describe", "info": "describe",
               "simulate": "run", "benchmark": "sweep", "view-report": "report"}  # fmt: skip
"""Commands by words other tools use for them, named when one is typed."""


class WorkbenchGroup(typer.core.TyperGroup):
    """The one place where a WorkbenchError becomes a one-line message and exit code 2.

    A command's bad arguments (``--rtol abc``, an unknown option) are one line too, with
    the command's help to turn to; ``workbench COMMAND`` alone still prints its usage."""

    def get_command(self, ctx: click.Context, cmd_name: str) -> Any:
        command = super().get_command(ctx, cmd_name)
        if command is not None and command.help:
            command.help = reflowed(command.help)
        return command

    def resolve_command(self, ctx: click.Context, args: list[str]) -> Any:
        """An unknown command names the one meant where it is another tool's word for it
        (``workbench plugins``: ``workbench list``); click's own close-spelling hints stay."""
        try:
            return super().resolve_command(ctx, args)
        except USAGE_ERRORS as error:
            meant = OTHER_WORDS.get(args[0]) if args else None
            if meant is not None:
                error.message = f"{error.message.rstrip('.')}; did you mean `workbench {meant}`?"
            raise

    def invoke(self, ctx: click.Context) -> Any:
        _ON_INTERRUPT.clear()
        try:
            return super().invoke(ctx)
        except WorkbenchError as error:
            raise fail(error) from None
        except BrokenPipeError as error:
            if _stdout_reader_gone():  # `workbench ... | head` had what it wanted: Click
                raise  # ends quietly (exit 1), as it does for its own output
            typer.echo(f"error: {os_error_line(error)}", err=True)
            raise typer.Exit(EXIT_BAD_INPUT) from None
        except OSError as error:  # a full or read-only disk, a path that is not a directory
            typer.echo(f"error: {os_error_line(error)}", err=True)
            raise typer.Exit(EXIT_BAD_INPUT) from None
        except KeyboardInterrupt:
            typer.echo(f"interrupted: {interrupted_line()}", err=True)
            raise typer.Exit(EXIT_INTERRUPTED) from None
        except NO_ARGS_IS_HELP:
            raise
        except USAGE_ERRORS as error:
            command = error.ctx.command_path if error.ctx is not None else "workbench"
            text = one_line_text(error.format_message())
            typer.echo(f"error: {text} (see {command} --help)", err=True)
            raise typer.Exit(EXIT_BAD_INPUT) from None


app = typer.Typer(
    cls=WorkbenchGroup,
    name="workbench",
    help="Compare formalisms and integrators for multibody dynamics.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)


def option_value(text: str) -> Any:
    """A ``-o`` value as TOML (1, 1e-3, true, "x", [1, 2]); a bare word stays a string."""
    import tomllib

    try:
        return tomllib.loads(f"value = {text}")["value"]
    except tomllib.TOMLDecodeError:
        return text


def refuse_short_out(value: str | None, command: str) -> None:
    """``-o`` means ``--option NAME=VALUE`` in every command that takes options (run,
    describe); where it used to mean the output directory (sweep, report) it is refused
    with the long form to use instead."""
    if value is not None:
        raise ConfigError(
            f"{command}: -o is --option NAME=VALUE (workbench run, describe); the output "
            f"directory is --out: {command} ... --out {value}"
        )


@contextmanager
def warnings_on_stderr() -> Iterator[None]:
    """Python warnings raised inside (unreadable rows, plugins left out), one line each on
    stderr when it ends, however it ends: not Python's two-line form naming our source."""
    import warnings

    caught: list[warnings.WarningMessage] = []
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            yield
    finally:
        for warning in caught:
            typer.echo(f"warning: {warning.message}", err=True)


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


def main() -> None:
    """Console-script entry point (``workbench``)."""
    try:
        app()
    except WorkbenchError as error:  # raised outside a command (e.g. by a callback)
        sys.exit(fail(error).exit_code)
    except KeyboardInterrupt:  # outside a command (e.g. while importing)
        typer.echo("interrupted: stopped by Ctrl-C; files already written are kept", err=True)
        sys.exit(EXIT_INTERRUPTED)


# the --cost of report, paper and results: the measure they rank in
CostOption = Annotated[
    str | None,
    typer.Option(
        "--cost",
        help="Cost measure of the diagrams, tables and recommendation: integrate_cpu "
        "(default), integrate_wall, n_rhs or work (counted work: evaluations weighted "
        "by their unit CPU costs, docs/reports.md). A sweep resumed into RESULTS, and "
        "report and paper without --cost, keep the measure chosen here.",
    ),
]
