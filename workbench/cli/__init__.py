"""The ``workbench`` command line: the app and one module a command group.

``app`` holds what every command shares (one-line errors, exit code 2 on bad input, the
console); ``plugins`` (list, describe, new), ``runs`` (run, sweep, results, reference),
``outputs`` (report, view, paper) and ``cache`` (info, clear) add their commands to it
when imported here.
"""

from workbench.cli import cache, outputs, plugins, runs  # noqa: F401 - register the commands
from workbench.cli.app import app, main

__all__ = ["app", "main"]
