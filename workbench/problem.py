"""Deprecated name of :mod:`workbench.plugin.problem`, kept for one release (docs/plugins.md).

Plugins written against ``workbench.problem`` keep working; import from
``workbench.plugin.problem`` instead.
"""

import warnings

from workbench.plugin import problem as _moved

warnings.warn(
    "workbench.problem is deprecated: import from workbench.plugin.problem",
    DeprecationWarning,
    stacklevel=2,
)


def __getattr__(name: str):
    return getattr(_moved, name)
