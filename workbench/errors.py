"""The workbench's exceptions: every message names the thing at fault and what would fix it."""


class WorkbenchError(Exception):
    """Base of every error the workbench raises on purpose."""


class ModelError(WorkbenchError):
    """A mechanism model is inconsistent (bad parameter, unknown name, bad topology)."""


class PluginError(WorkbenchError):
    """A plugin is unknown, broken, or cannot handle what it was asked to do."""


class ConfigError(WorkbenchError):
    """A run, sweep specification or option value is invalid."""


class IntegrationError(WorkbenchError):
    """Initialisation or integration of the equations of motion failed."""
