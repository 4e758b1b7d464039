"""Deprecated name of :mod:`workbench.plugin.integrator`, kept for one release (docs/plugins.md).

Plugins written against ``workbench.integrator`` keep working; import from
``workbench.plugin.integrator`` instead.
"""

import warnings

from workbench.plugin import integrator as _moved

warnings.warn(
    "workbench.integrator is deprecated: import from workbench.plugin.integrator",
    DeprecationWarning,
    stacklevel=2,
)


def __getattr__(name: str):
    return getattr(_moved, name)
