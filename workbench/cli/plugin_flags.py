"""The options every command that uses plugins shares: ``--plugins`` and ``--no-local-plugins``.

``workbench run``, ``describe``, ``list`` and ``sweep`` (and ``python -m workbench.testing``)
take ``--plugins MODULE_OR_FILE`` (repeatable: an installed module or a module or ``.py``
file of the current directory, imported before anything else is looked up) and a plugin named
as ``MODULE_OR_FILE:Class`` where a registered name goes; ``--no-local-plugins`` (or
``WORKBENCH_NO_LOCAL_PLUGINS=1``) refuses every local module
(:mod:`workbench.plugin.local_modules`).
"""

from __future__ import annotations

from typing import Annotated

import typer

from workbench.plugin.local_modules import NO_LOCAL_PLUGINS_VARIABLE, PluginModule, load_plugins

PluginsOption = Annotated[
    list[str] | None,
    typer.Option(
        "--plugins",
        help="Import this plugin module first: an installed module, or a module or .py file "
        "here (repeatable; MODULE_OR_FILE:Class also registers that class).",
    ),
]
NoLocalPluginsOption = Annotated[
    bool,
    typer.Option(
        "--no-local-plugins",
        help="Import no local plugin module, only installed ones "
        f"(also {NO_LOCAL_PLUGINS_VARIABLE}=1).",
    ),
]


def plugins_from_flags(
    plugins: list[str] | None, no_local: bool, *references: str
) -> tuple[list[PluginModule], list[str]]:
    """Apply the flags: the modules imported and each of ``references`` as a registered
    name (a ``MODULE_OR_FILE:Class`` one is imported and named by its class)."""
    allow_local = False if no_local else None  # None: unless WORKBENCH_NO_LOCAL_PLUGINS
    modules, names = load_plugins(plugins or [], references, allow_local)
    return modules, [names.get(reference, reference) for reference in references]
