"""``workbench cache``: the compiled-library cache that ``compile = "jit"`` or ``"auto"`` fills.

Compiled equations are kept on disk (``$WORKBENCH_CACHE``, else ~/.cache/mbs-workbench),
shared by workers and sweeps, trimmed to ``$WORKBENCH_CACHE_LIMIT_MB``
(:mod:`workbench.equations.compiled`); this shows it and empties it.
"""

from __future__ import annotations

from typing import Annotated

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

    count, size = compiled.cache_size()
    limit = compiled.cache_limit_bytes()
    typer.echo(
        f"{compiled.cache_dir()}: {count} compiled libraries, {_megabytes(size)} "
        f"(limit {_megabytes(limit)}: WORKBENCH_CACHE_LIMIT_MB)"
    )


@cache_app.command("clear")
def clear(
    yes: Annotated[bool, typer.Option("--yes", "-y", help="Do not ask.")] = False,
) -> None:
    """Remove every compiled library (the next jit run compiles again)."""
    from workbench.equations import compiled

    count, size = compiled.cache_size()
    if (
        count
        and not yes
        and not typer.confirm(
            f"remove {count} compiled libraries ({_megabytes(size)}) from {compiled.cache_dir()}?"
        )
    ):
        raise typer.Exit(1)
    removed = compiled.clear_cache()
    typer.echo(f"removed {removed} compiled libraries from {compiled.cache_dir()}")
