"""mbs-workbench: compare formalisms and integrators for multibody dynamics.

The core knows no particular formalism, integrator or problem: those are plugins found
through :mod:`workbench.registry`.
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
