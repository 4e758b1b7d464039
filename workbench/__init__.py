"""mbs-workbench: compare formalisms and integrators for multibody dynamics.

The core knows no particular formalism, integrator or problem: those are plugins found
through :mod:`workbench.plugin.registry`.
"""

from workbench.errors import (
    ConfigError,
    IntegrationError,
    ModelError,
    PluginError,
    WorkbenchError,
)

__all__ = ["ConfigError", "IntegrationError", "ModelError", "PluginError", "WorkbenchError"]
__version__ = "0.1.0"


def __getattr__(name: str):
    """``workbench.load_results(PATH)``, imported lazily (pandas is not needed otherwise)."""
    if name in ("load_results", "load_series"):
        from workbench.runs import store

        return getattr(store, name)
    raise AttributeError(f"module 'workbench' has no attribute {name!r}")
