"""Deprecated name of :mod:`workbench.plugin.options`, kept for one release (docs/plugins.md)."""

from workbench.plugin.moved import moved_module

__getattr__ = moved_module(__name__, "workbench.plugin.options")
