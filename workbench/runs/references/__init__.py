"""Deprecated name of :mod:`workbench.execution.references`, kept for one release
(docs/plugins.md names ``workbench.runs.references.given_reference``).

A package rather than a ``references.py`` file, so git follows the old file to its new
place when branches that edited it are merged.
"""

from workbench.plugin.moved import moved_module

__getattr__ = moved_module(__name__, "workbench.execution.references")
