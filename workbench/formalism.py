"""Deprecated name of :mod:`workbench.plugin.formalism`, kept for one release (docs/plugins.md).

Plugins written against ``workbench.formalism`` keep working; import from
``workbench.plugin.formalism`` instead.
"""

import warnings

from workbench.plugin import formalism as _moved

warnings.warn(
    "workbench.formalism is deprecated: import from workbench.plugin.formalism",
    DeprecationWarning,
    stacklevel=2,
)


def __getattr__(name: str):
    return getattr(_moved, name)
