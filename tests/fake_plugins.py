"""Plugins for the runner and sweep tests, loaded with ``plugins = ["tests.fake_plugins"]``.

Small inline problems (a rigid pendulum, a slider-crank loop), a tolerance-controlled
test integrator (``test-rk45``, SciPy's RK45 on the ode form), a fixed-step RK4, and
misbehaving plugins: an integrator that hangs, one that raises, one that returns NaN, one
that kills its own process, and a formalism that raises at build. Importing this module
registers them in the global registry (tests restore the registry afterwards).
"""

from __future__ import annotations

import faulthandler
import os
import signal
import time
from dataclasses import dataclass

import numpy as np
import scipy.integrate

from workbench.model import Frame, Model
from workbench.plugin.integrator import IntegrationTask, Integrator, Trajectory
from workbench.plugin.problem import Problem, Reference
from workbench.plugin.registry import formalism, integrator, problem
from workbench.plugins.formalisms.minimal_ode import MinimalOde


@dataclass(frozen=True)
class PendulumOptions:
    initial_angle: float = 1.0


@problem
class TestPendulum(Problem):
    name = "test-pendulum"
    summary = "Rigid planar pendulum (test)"
    source = "tests"
    Options = PendulumOptions
    t_end = 2.0
    n_samples = 41

    def model(self) -> Model:
        model = Model("test-pendulum", kind="planar", gravity=(0.0, -9.81, 0.0))
        model.add_body("link", 1.0, com=(0.5, 0, 0), inertia=0.1)
        model.add_joint("pivot", "revolute", "ground", "link")
        return model

    def initial_joint_coordinates(self) -> dict[str, float]:
        return {"pivot": -self.options.initial_angle}


@problem
class TestSliderCrank(Problem):
    name = "test-slider-crank"
    summary = "Planar slider-crank loop (test)"
    source = "tests"
    independent_coordinates = (("j1", 0),)
    t_end = 0.5
    n_samples = 26

    def model(self) -> Model:
        model = Model("test-slider-crank", kind="planar")
        model.add_body("crank", 1, com=(0.05, 0, 0), inertia=0.01)
        model.add_body("rod", 1, com=(0.2, 0, 0), inertia=0.02)
        model.add_body("slider", 1, inertia=0.01)
        model.add_joint("j1", "revolute", "ground", "crank")
        model.add_joint("j2", "revolute", "crank", "rod", parent_frame=Frame.at(0.1))
        model.add_joint("j3", "prismatic", "ground", "slider", axis=(1, 0, 0))
        model.add_joint("j4", "revolute", "rod", "slider", parent_frame=Frame.at(0.4), cut=True)
        return model

    def initial_joint_coordinates(self) -> dict[str, float]:
        return {"j1": 1.0, "j3": 0.45, "j2": -1.2}

    def initial_joint_velocities(self) -> dict[str, float]:
        return {"j1": 10.0}


@formalism
class BrokenBuild(MinimalOde):
    name = "test-broken-build"
    summary = "Raises at build (test)"

    def build(self, model, options=None):
        raise RuntimeError("this formalism always fails to build")


@formalism
class TreesOnly(MinimalOde):
    name = "test-trees-only"
    summary = "minimal-ode without closed loops (test)"
    capabilities = frozenset({"planar", "spatial", "point-masses"})


@integrator
class TestRk45(Integrator):
    name = "test-rk45"
    summary = "SciPy RK45 on the ode form (test)"
    accepts = {"ode": 0}

    def integrate(self, task: IntegrationTask, trajectory: Trajectory) -> None:
        ode = task.form

        def rhs(t, y):
            return ode.rhs.into(t, y)[0].copy()

        solution = scipy.integrate.solve_ivp(
            rhs,
            (task.times[0], task.times[-1]),
            task.y0,
            method="RK45",
            t_eval=task.times,
            rtol=task.rtol,
            atol=task.atol,
        )
        trajectory.times = solution.t
        trajectory.y = solution.y.T
        trajectory.stats.n_steps = max(1, (solution.nfev - 1) // 6)
        if not solution.success:
            trajectory.success, trajectory.message = False, solution.message


@dataclass(frozen=True)
class Rk4Options:
    steps_per_sample: int = 10


@integrator
class TestRk4(Integrator):
    name = "test-rk4"
    summary = "Classical fixed-step RK4 on the ode form (test)"
    accepts = {"ode": 0}
    Options = Rk4Options

    def integrate(self, task: IntegrationTask, trajectory: Trajectory) -> None:
        f = task.form.rhs
        y = task.y0.copy()
        out = [y.copy()]
        n = task.options.steps_per_sample
        for t0, t1 in zip(task.times[:-1], task.times[1:], strict=True):
            h = (t1 - t0) / n
            t = t0
            for _ in range(n):
                k1 = f.into(t, y)[0].copy()
                k2 = f.into(t + h / 2, y + h / 2 * k1)[0].copy()
                k3 = f.into(t + h / 2, y + h / 2 * k2)[0].copy()
                k4 = f.into(t + h, y + h * k3)[0].copy()
                y = y + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
                t += h
            out.append(y.copy())
        trajectory.times = task.times
        trajectory.y = np.array(out)
        trajectory.stats.n_steps = n * (len(task.times) - 1)


@integrator
class Hang(TestRk45):
    name = "test-hang"
    summary = "Never returns (test)"

    def integrate(self, task, trajectory):
        while True:
            time.sleep(1.0)


@integrator
class Raise(TestRk45):
    name = "test-raise"
    summary = "Raises (test)"

    def integrate(self, task, trajectory):
        raise RuntimeError("the test integrator raised")


@integrator
class ReturnNan(TestRk45):
    name = "test-nan"
    summary = "Returns NaN after the first step (test)"

    def integrate(self, task, trajectory):
        trajectory.times = task.times
        trajectory.y = np.full((len(task.times), task.y0.size), np.nan)
        trajectory.y[0] = task.y0


@integrator
class Die(TestRk45):
    name = "test-die"
    summary = "Crashes its own process: SIGSEGV, as a fault in native code would (test)"

    def integrate(self, task, trajectory):
        faulthandler.disable()  # pytest's dump of the crash is noise here
        os.kill(os.getpid(), signal.SIGSEGV)


# what test-flaky does: hang | raise | kill | kill-parent, or one of them once (MODE-once)
FLAKY = "WORKBENCH_TEST_FLAKY"
FLAKY_MARKER = "WORKBENCH_TEST_FLAKY_MARKER"  # MODE-once: a file made the first time


@integrator
class Flaky(TestRk45):
    name = "test-flaky"
    summary = "test-rk45, unless $WORKBENCH_TEST_FLAKY says hang, raise or kill (test)"

    def integrate(self, task, trajectory):
        mode = os.environ.get(FLAKY, "")
        if mode.endswith("-once"):
            if os.path.exists(os.environ[FLAKY_MARKER]):
                mode = ""
            else:
                open(os.environ[FLAKY_MARKER], "w").close()
                mode = mode.removesuffix("-once")
        if mode == "kill":  # as an operator or the OOM killer would: not the run's fault
            os.kill(os.getpid(), signal.SIGKILL)
        if mode == "kill-parent":  # a Dask run's parent: its Dask worker
            os.kill(os.getppid(), signal.SIGKILL)
            time.sleep(60)
        if mode == "hang":
            while True:
                time.sleep(1.0)
        if mode == "raise":
            raise RuntimeError("test-flaky raised")
        super().integrate(task, trajectory)


@problem
class TestNonConservative(TestPendulum):
    name = "test-nonconservative"
    summary = "The rigid pendulum declared non-conservative (test)"
    conservative = False


@problem
class TestFalling(Problem):
    name = "test-falling"
    summary = "A block sliding down a vertical prismatic joint, analytic reference (test)"
    source = "tests"
    t_end = 1.0
    n_samples = 11

    def model(self) -> Model:
        model = Model("test-falling", kind="planar", gravity=(0.0, -9.81, 0.0))
        model.add_body("block", 2.0, inertia=0.1)
        model.add_joint("slide", "prismatic", "ground", "block", axis=(0, 1, 0))
        return model

    def reference(self) -> Reference:
        def poses(times: np.ndarray) -> np.ndarray:
            out = np.zeros((len(times), 1, 7))
            out[:, 0, 1] = -9.81 * np.asarray(times) ** 2 / 2
            out[:, 0, 3] = 1.0
            return out

        return Reference("analytic", poses, "y = -g t^2 / 2")


@integrator
class Picky(TestRk45):
    name = "test-picky"
    summary = "Refuses every equation (test)"

    def incompatibility(self, equations, options):
        return "it needs a constant mass matrix"
