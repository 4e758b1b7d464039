"""Deprecated name of :mod:`workbench.plugin.options`, kept for one release (docs/plugins.md).

Plugins written against ``workbench.options`` keep working; import from
``workbench.plugin.options`` instead.
"""

import warnings

from workbench.plugin import options as _moved

warnings.warn(
    "workbench.options is deprecated: import from workbench.plugin.options",
    DeprecationWarning,
    stacklevel=2,
)


def __getattr__(name: str):
    return getattr(_moved, name)
