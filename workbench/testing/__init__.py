"""Conformance suite for plugin authors: is my formalism, integrator or problem right?

Plain functions, usable from any package's pytest::

    from workbench.testing import check_formalism

    def test_my_formalism_conforms():
        check_formalism("my-formalism").raise_if_failed()

Each returns a :class:`ConformanceReport` whose rows say which check, on which problem,
the measured error and the tolerance; ``raise_if_failed()`` raises
:class:`ConformanceError` (an AssertionError) listing the failures. ``checks="structural"``
runs only the checks that need no physics (registration, metadata, options, declared
capabilities and forms). From a shell: ``python -m workbench.testing formalism NAME``.
"""

from workbench.testing.common import FAST_PROBLEMS
from workbench.testing.formalism import check_formalism
from workbench.testing.integrator import check_integrator
from workbench.testing.problem import check_problem
from workbench.testing.report import CheckResult, ConformanceError, ConformanceReport

__all__ = [
    "FAST_PROBLEMS",
    "CheckResult",
    "ConformanceError",
    "ConformanceReport",
    "check_formalism",
    "check_integrator",
    "check_problem",
]
