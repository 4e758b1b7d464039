"""The problem contract: what a catalog entry declares (SciMLBenchmarks-style: a document).

A problem plugin subclasses :class:`Problem` and registers with
``@workbench.registry.problem``. It must:

1. set ``name``, ``summary`` (one line) and ``source`` (the book section it follows);
2. implement :meth:`Problem.model` returning a :class:`~workbench.model.Model`
   (parameters in SI units, documented in the module docstring);
3. set ``t_end`` (and ``t_start`` if not 0) and ``n_samples`` (output times);
4. implement :meth:`initial_joint_coordinates` / :meth:`initial_joint_velocities`:
   values for the spanning-tree joints that are not driven (joints left out start at
   their neutral value / at rest);
5. optionally declare ``independent_coordinates`` (joint name, index) kept fixed when the
   initial state is projected onto the loop-closure and nonholonomic constraints;
6. declare ``conservative`` (energy conserved) and :meth:`invariants` (other conserved
   quantities);
7. optionally give a :meth:`reference`: analytic body poses; without one, a stored
   trajectory in ``references/`` beside the module (``workbench reference NAME``) is used.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from workbench.model import Model
from workbench.options import NoOptions, parse_options


@dataclass(frozen=True)
class Invariant:
    """A quantity conserved along exact solutions.

    ``function(model, t, poses, twists)`` -> float, where poses is (n_bodies, 7)
    [position, quaternion scalar-first] and twists is (n_bodies, 6) [velocity of the
    body frame origin, angular velocity], both in inertial coordinates.
    """

    name: str
    function: Callable[[Model, float, np.ndarray, np.ndarray], float]


@dataclass(frozen=True)
class Reference:
    """Reference body poses at given times: ``poses(times) -> (n_times, n_bodies, 7)``.

    kind: "analytic" or "stored"; ``description`` says how it was obtained.
    """

    kind: str
    poses: Callable[[np.ndarray], np.ndarray]
    description: str = ""


class Problem:
    """Base class of catalog problems (see the module docstring for the contract)."""

    name: ClassVar[str] = ""
    summary: ClassVar[str] = ""
    source: ClassVar[str] = ""
    Options: ClassVar[type] = NoOptions
    t_start: ClassVar[float] = 0.0
    t_end: ClassVar[float] = 1.0
    n_samples: ClassVar[int] = 101
    conservative: ClassVar[bool] = True
    independent_coordinates: ClassVar[tuple[tuple[str, int], ...] | None] = None

    def __init__(self, options: Any = None) -> None:
        self.options = parse_options(self.Options, options, f"problem {self.name!r}")

    def model(self) -> Model:
        raise NotImplementedError(f"problem {self.name!r} must implement model()")

    def initial_joint_coordinates(self) -> dict[str, Any]:
        return {}

    def initial_joint_velocities(self) -> dict[str, Any]:
        return {}

    def invariants(self) -> list[Invariant]:
        return []

    def reference(self) -> Reference | None:
        """Analytic poses (override this), else the stored reference written by
        ``workbench reference NAME`` into ``references/`` beside the problem's module, when
        it matches the problem's options and model (:mod:`workbench.references`), else None."""
        from workbench.references import stored_reference

        return stored_reference(self)

    def sample_times(self) -> np.ndarray:
        return np.linspace(self.t_start, self.t_end, self.n_samples)
