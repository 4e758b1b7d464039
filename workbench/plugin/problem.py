"""The problem contract: what a catalog entry declares (SciMLBenchmarks-style: a document).

A problem plugin subclasses :class:`Problem` and registers with
``@workbench.plugin.registry.problem``. It must:

1. set ``name``, ``summary`` (one line) and ``source`` (the book section it follows);
2. implement :meth:`Problem.model` returning a :class:`~workbench.model.Model`
   (parameters in SI units, documented in the module docstring); the base class sets the
   returned model's ``initial_configuration`` to :meth:`initial_joint_coordinates` (unless
   ``model()`` set one), so the rank of the constraints, the degrees of freedom and any
   redundant rows are decided at the problem's initial configuration, not at the neutral
   one (which can be singular) — by ``workbench describe`` and every formalism alike;
3. set ``t_end`` (and ``t_start`` if not 0) and ``n_samples`` (output times);
4. implement :meth:`initial_joint_coordinates` / :meth:`initial_joint_velocities`:
   values for the spanning-tree joints that are not driven (joints left out start at
   their neutral value / at rest);
5. optionally declare ``independent_coordinates`` (joint name, index within that joint's
   coordinates) kept fixed when the initial state is projected onto the loop-closure and
   nonholonomic constraints: at most as many as the degrees of freedom;
6. declare ``conservative`` (energy conserved: no drive, damping or applied force does
   work; a property when it depends on the options) and :meth:`invariants` (other
   conserved quantities);
7. optionally give a :meth:`reference`: analytic body poses. Without one, a stored
   trajectory in ``references/`` beside the module (``workbench reference NAME``) is used,
   else a computed one: that choice is made by :mod:`workbench.runs.references`;
8. optionally implement :meth:`unavailable`: when the problem needs files from a package
   that is not installed (robot files of an extra), say so there; its runs are then
   ``skipped`` rows with that reason, so a sweep plans the same runs on every install;
9. optionally declare ``benchmark``, when the problem belongs to a published benchmark
   suite that scores codes by a required precision: a dict with ``suite`` (e.g.
   "iftomm", "ivp"), ``precision`` (the bound), ``measure`` (the result column compared
   with it, e.g. "err_max" or "energy_err_max") and ``variables`` (what the benchmark
   itself measures, in words). The report's scorecards are built from it.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from workbench.errors import PluginError
from workbench.model import Model
from workbench.plugin.options import NoOptions, parse_options


@dataclass(frozen=True)
class Invariant:
    """A quantity conserved along exact solutions.

    ``function(model, t, poses, twists)`` -> float, where poses is (n_bodies, 7)
    [position, quaternion scalar-first] and twists is (n_bodies, 6) [velocity of the
    body frame origin, angular velocity], both in inertial coordinates.

    ``vectorized=True`` declares that ``function`` also broadcasts over a leading sample
    axis: t (n,), poses (n, n_bodies, 7), twists (n, n_bodies, 6) -> (n,). Metrics then
    evaluate it along a trajectory in one call instead of one call per output sample
    (which cost the default sweep seconds of Python); the conformance suite checks that
    both give the same values.
    """

    name: str
    function: Callable[[Model, Any, np.ndarray, np.ndarray], Any]
    vectorized: bool = False

    def along(
        self, model: Model, times: np.ndarray, poses: np.ndarray, twists: np.ndarray
    ) -> np.ndarray:
        """Values (n,) at n samples: times (n,), poses (n, n_bodies, 7), twists
        (n, n_bodies, 6)."""
        times = np.asarray(times, dtype=float).reshape(-1)
        if self.vectorized:
            values = np.asarray(self.function(model, times, poses, twists), dtype=float)
            if values.shape != times.shape:
                raise ValueError(
                    f"invariant {self.name!r} is declared vectorized but returned shape "
                    f"{values.shape} for {times.size} samples (expected {times.shape}); make "
                    "it broadcast over the leading sample axis or set vectorized=False"
                )
            return values
        values = []
        for t, p, w in zip(times, poses, twists, strict=True):
            value = np.asarray(self.function(model, t, p, w), dtype=float)
            if value.size != 1:
                raise ValueError(
                    f"invariant {self.name!r} returned shape {value.shape} for one sample "
                    f"(expected a number); it is called with one sample's poses "
                    f"{np.shape(p)} and twists {np.shape(w)}, bodies on the first axis "
                    "(e.g. twists[k, 5]), unless declared vectorized=True"
                )
            values.append(value.item())
        return np.array(values)


@dataclass(frozen=True)
class Reference:
    """Reference body poses at given times: ``poses(times) -> (n_times, n_bodies, 7)``.

    kind: "analytic" or "stored"; ``description`` says how it was obtained; ``accuracy``:
    the relative pose error (of the length scale) the reference itself can be trusted to,
    so that no run is credited with more correct digits than it supports (analytic
    references default to ANALYTIC_ACCURACY: round-off of their evaluation).
    """

    kind: str
    poses: Callable[[np.ndarray], np.ndarray]
    description: str = ""
    accuracy: float = math.nan


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
    benchmark: ClassVar[dict[str, Any] | None] = None

    def __init__(self, options: Any = None) -> None:
        self.options = parse_options(self.Options, options, f"problem {self.name!r}")

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        if "model" in cls.__dict__:
            cls.model = _with_initial_configuration(cls.__dict__["model"])

    def model(self) -> Model:
        raise NotImplementedError(f"problem {self.name!r} must implement model()")

    def initial_joint_coordinates(self) -> dict[str, Any]:
        return {}

    def initial_joint_velocities(self) -> dict[str, Any]:
        return {}

    def invariants(self) -> list[Invariant]:
        return []

    def reference(self) -> Reference | None:
        """Analytic poses, if the problem has them (override this); None otherwise.

        A declaration only: the stored and computed references are found by
        :func:`workbench.runs.references.given_reference` and ``problem_reference``."""
        return None

    def unavailable(self) -> str | None:
        """What this problem needs that is not installed, in one line with the command that
        installs it (e.g. ``pip install "mbs-workbench[robots]"``); None when it can run."""
        return None

    def describe_rows(self) -> list[tuple[str, str]]:
        """Extra (property, value) rows ``workbench describe`` shows in the model table
        (e.g. what an imported file holds beyond the model); none by default."""
        return []

    def sample_times(self) -> np.ndarray:
        return np.linspace(self.t_start, self.t_end, self.n_samples)


def _with_initial_configuration(build: Callable[[Problem], Model]) -> Callable[[Problem], Model]:
    """Wrap a problem's ``model()`` so the model carries the problem's initial joint
    coordinates as its ``initial_configuration`` (contract item 2)."""

    @functools.wraps(build)
    def model(self: Problem) -> Model:
        built = build(self)
        if not isinstance(built, Model):
            raise PluginError(
                f"problem {self.name!r}: model() returned {type(built).__name__}, not a "
                "workbench.model.Model; end it with `return model`"
            )
        if not built.initial_configuration:
            coordinates = self.initial_joint_coordinates()
            if not isinstance(coordinates, Mapping):
                raise PluginError(
                    f"problem {self.name!r}: initial_joint_coordinates() returned "
                    f"{type(coordinates).__name__}, not a mapping of joint name -> value(s); "
                    "return e.g. {'pivot': 0.3}"
                )
            built.initial_configuration = dict(coordinates)
        return built

    return model
