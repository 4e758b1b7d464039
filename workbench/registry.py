"""Deprecated name of :mod:`workbench.plugin.registry`, kept for one release (docs/plugins.md).

Plugins written against ``workbench.registry`` keep working; import from
``workbench.plugin.registry`` instead.
"""

import warnings

from workbench.plugin import registry as _moved

warnings.warn(
    "workbench.registry is deprecated: import from workbench.plugin.registry",
    DeprecationWarning,
    stacklevel=2,
)


def __getattr__(name: str):
    return getattr(_moved, name)
