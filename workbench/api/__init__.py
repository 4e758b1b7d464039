"""The public Python API: the CLI's verbs for notebooks and scripts.

``workbench.run``, ``workbench.sweep``, ``workbench.describe``, ``workbench.load_results``,
``workbench.report`` and ``workbench.paper``, and the registry's list
(``workbench.list_plugins(kind)``), a thin layer beside the CLI over the same calls
(``workbench.execution`` for one run, ``workbench.runs`` for sweeps). Everything here is
also importable from ``workbench`` itself, lazily (``import workbench`` stays cheap).
"""

from workbench.api.catalog import Description, describe, list_plugins
from workbench.api.plots import plot_work_precision
from workbench.api.reports import paper, report
from workbench.api.result import Result
from workbench.api.runs import run
from workbench.api.sweeps import record, sweep
from workbench.runs.store import load_results, load_series, load_trajectory

__all__ = [
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
]
