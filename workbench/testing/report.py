"""Results of conformance checks: one row per (check, problem), a report, an error.

A :class:`CheckResult` says which check, on which subject (plugin) and problem, whether it
passed, the measured error and the tolerance it was held to, so a failure reads e.g.
``FAIL accelerations  my-formalism  double-pendulum  error 3.2e-01 > 1e-08  ...``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

from workbench.errors import one_line_text

Status = Literal["pass", "fail", "skip"]


@dataclass
class CheckResult:
    """One check of one plugin on one problem (``problem`` is "" for structural checks)."""

    check: str
    subject: str
    problem: str
    status: Status
    error: float = math.nan
    tolerance: float = math.nan
    message: str = ""

    def __post_init__(self) -> None:
        self.message = one_line_text(self.message)  # a check's message is one line

    def line(self) -> str:
        size = ""
        if not math.isnan(self.error):
            relation = "<=" if self.status == "pass" else ">"
            bound = f" {relation} {self.tolerance:.2g}" if not math.isnan(self.tolerance) else ""
            size = f"error {self.error:.2e}{bound}"
        parts = [f"{self.status.upper():4}", f"{self.check:22}", f"{self.problem or '-':26}"]
        return "  ".join(parts + [size, self.message]).rstrip()


class ConformanceError(AssertionError):
    """Raised by :meth:`ConformanceReport.raise_if_failed`; its message lists the failures."""


@dataclass
class ConformanceReport:
    """All results of checking one plugin (``kind`` formalism, integrator or problem)."""

    kind: str
    subject: str
    results: list[CheckResult] = field(default_factory=list)
    span: float = math.nan  # s of the motion checks' run, said by the summary (NaN: none)

    def add(
        self,
        check: str,
        problem: str,
        error: float,
        tolerance: float,
        message: str = "",
    ) -> CheckResult:
        """Record a measured ``error`` against ``tolerance`` (NaN error fails)."""
        status: Status = "pass" if error <= tolerance else "fail"
        result = CheckResult(
            check, self.subject, problem, status, float(error), float(tolerance), message
        )
        self.results.append(result)
        return result

    def passed(self, check: str, problem: str = "", message: str = "") -> None:
        self.results.append(CheckResult(check, self.subject, problem, "pass", message=message))

    def failed(self, check: str, problem: str, message: str) -> None:
        self.results.append(CheckResult(check, self.subject, problem, "fail", message=message))

    def skipped(self, check: str, problem: str, message: str) -> None:
        self.results.append(CheckResult(check, self.subject, problem, "skip", message=message))

    @property
    def failures(self) -> list[CheckResult]:
        return [r for r in self.results if r.status == "fail"]

    @property
    def ok(self) -> bool:
        return not self.failures

    def summary(self) -> str:
        counts = {s: sum(r.status == s for r in self.results) for s in ("pass", "fail", "skip")}
        text = (
            f"{self.kind} {self.subject!r}: {counts['pass']} passed, {counts['fail']} failed, "
            f"{counts['skip']} skipped"
        )
        if math.isnan(self.span):
            return text
        return f"{text}; trajectory checked over {self.span:g} s, not a run's whole time span"

    def __str__(self) -> str:
        return "\n".join([self.summary(), *(r.line() for r in self.results)])

    def raise_if_failed(self) -> ConformanceReport:
        """Raise :class:`ConformanceError` listing the failed checks; return self otherwise."""
        if self.failures:
            lines = [self.summary(), *(r.line() for r in self.failures)]
            raise ConformanceError("\n".join(lines))
        return self
