"""``workbench cache``: the compiled-library cache that ``compile = "jit"`` or ``"auto"`` fills.

Compiled equations are kept on disk (``$WORKBENCH_CACHE``, else ~/.cache/mbs-workbench),
shared by workers and sweeps, trimmed to ``$WORKBENCH_CACHE_LIMIT_MB``
(:mod:`workbench.equations.compiled`); this shows it and empties it.
"""

from __future__ import annotations

from typing import Annotated, Any

import typer

from workbench.cli.app import app

cache_app = typer.Typer(help="The cache of compiled equations (compile = jit or auto).")
app.add_typer(cache_app, name="cache")


def _megabytes(size: int) -> str:
    return f"{size / 2**20:.1f} MB"


@cache_app.command("info")
def info() -> None:
    """Where the cache is, how many compiled libraries it holds and their size."""
    from workbench.equations import compiled

    directory = _usable_cache_dir()
    limit, wrong = compiled.cache_limit()
    if wrong:
        typer.echo(f"note: {wrong}", err=True)
    if not directory.is_dir():
        typer.echo(f"{directory}: no compiled library yet (made at the first compile)")
        return
    count, size = compiled.cache_size()
    typer.echo(
        f"{directory}: {count} compiled libraries, {_megabytes(size)} "
        f"(limit {_megabytes(limit)}: WORKBENCH_CACHE_LIMIT_MB)"
    )


def _usable_cache_dir() -> Any:
    """The cache folder (:func:`workbench.files.usable_cache_dir`)."""
    from workbench.files import usable_cache_dir

    return usable_cache_dir()


@cache_app.command("clear")
def clear(
    yes: Annotated[bool, typer.Option("--yes", "-y", help="Do not ask.")] = False,
) -> None:
    """Remove every compiled library (the next jit run compiles again)."""
    from workbench.equations import compiled

    directory = _usable_cache_dir()
    count, size = compiled.cache_size() if directory.is_dir() else (0, 0)
    if (
        count
        and not yes
        and not typer.confirm(
            f"remove {count} compiled libraries ({_megabytes(size)}) from {directory}?"
        )
    ):
        typer.echo("nothing removed")
        raise typer.Exit(1)
    removed = compiled.clear_cache()
    typer.echo(f"removed {removed} compiled libraries from {compiled.cache_dir()}")
