"""mbs-workbench: compare formalisms and integrators for multibody dynamics.

The core knows no particular formalism, integrator or problem: those are plugins found
through :mod:`workbench.plugin.registry`. The public Python API (``workbench.run``,
``sweep``, ``describe``, ``load_results``...) is :mod:`workbench.api`, exported here.
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


# the public Python API (workbench.api), imported at first use: ``import workbench`` stays
# cheap (no pandas, CasADi or plugins until one of these is asked for)
API = (
    "Description",
    "Result",
    "describe",
    "list_plugins",
    "load_results",
    "load_series",
    "load_trajectory",
    "paper",
    "plot_work_precision",
    "record",
    "report",
    "run",
    "sweep",
)


def __getattr__(name: str):
    """``workbench.run(...)``, ``workbench.sweep(...)``... (:mod:`workbench.api`), lazily."""
    if name in API:
        from workbench import api

        return getattr(api, name)
    raise AttributeError(f"module 'workbench' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted([*globals(), *API])
