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


def one_line(error: BaseException, with_type: bool = True) -> str:
    """``error`` as one line of text: its message's non-empty lines joined with ' | '.

    ``with_type``: start with the exception's type as a traceback names it
    (``ValueError: ...``, ``numpy.linalg.LinAlgError: ...``; this module's own errors by
    their names alone, ``ModelError: ...``), which is what a
    plugin's error needs to be recognized; the command line leaves it out, its
    WorkbenchErrors being messages written for the user. A message-less error is its
    type's name either way. Notes added to the error (``add_note``) are not shown.
    """
    try:
        text = str(error)
    except Exception:  # noqa: BLE001 - a broken __str__ must not hide the error
        text = "<exception str() failed>"
    message = one_line_text(text)
    if not with_type:
        return message or type(error).__name__
    kind = type(error)
    name = kind.__qualname__
    if kind.__module__ not in ("builtins", "__main__", __name__):  # ours by their names
        name = f"{kind.__module__}.{name}"
    return f"{name}: {message}" if message else name


CASADI_NEWTON_ADVICE = "Set 'error_on_fail' option to false to ignore this error."
"""CasADi's advice after a rootfinder's failure: for CasADi's own users, not ours."""
NEWTON_FAILED = "(a Newton solve inside the equations did not converge)"


def one_line_text(text: object) -> str:
    """``text`` as one line: its non-empty lines, stripped, joined with ' | '.

    What every ``message`` of a result row goes through (the row schema says one line).
    """
    lines = " | ".join(line.strip() for line in str(text).splitlines() if line.strip())
    return lines.replace(CASADI_NEWTON_ADVICE, NEWTON_FAILED)
