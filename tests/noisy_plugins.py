"""Plugins that print, for the per-run log tests (``plugins = ["tests.noisy_plugins"]``).

- ``test-nan-force``: a point mass on a spring whose applied force turns NaN at t = 0.5 s,
  so a real IDA (CasADi's IDAS) fails there and says so on the C library's stderr;
- ``test-noisy-hang``: writes a line to file descriptor 2, then hangs;
- ``test-noisy``: SciPy's RK45 on the ode form that first writes NOISE_BYTES: half through
  Python's ``print`` (sys.stdout), half straight to file descriptor 2 as C code does,
  between a first line FIRST_LINE and a last line LAST_LINE.
"""

from __future__ import annotations

import math
import os
import sys
import time

import casadi as ca
import numpy as np
import scipy.integrate

from workbench.model import AppliedForce, JointSpringDamper, Model
from workbench.plugin.integrator import IntegrationTask, Integrator, Trajectory
from workbench.plugin.problem import Problem
from workbench.plugin.registry import integrator, problem

NOISE_BYTES = 50 * 1024 * 1024
FIRST_LINE = "noisy plugin: first line"
LAST_LINE = "noisy plugin: last line"


@problem
class NanForce(Problem):
    name = "test-nan-force"
    summary = "Spring-mass whose applied force is NaN after t = 0.5 s (test)"
    source = "tests"
    t_end = 1.0
    n_samples = 11

    def model(self) -> Model:
        model = Model("nan-force", kind="planar")
        model.add_point_mass("mass", 1.0)
        model.add_joint("slide", "prismatic", "ground", "mass", axis=(1, 0, 0))
        model.add_force(JointSpringDamper("spring", "slide", 4.0))

        def force(t, position, rotation, velocity, angular_velocity):
            return ca.vertcat(ca.if_else(t > 0.5, math.nan, 0.0), 0, 0), ca.DM.zeros(3)

        model.add_force(AppliedForce("nan-after-half-second", "mass", np.zeros(3), force))
        return model

    def initial_joint_coordinates(self) -> dict[str, float]:
        return {"slide": 0.1}


@integrator
class Noisy(Integrator):
    name = "test-noisy"
    summary = "SciPy RK45 that prints 50 MB first (test)"
    accepts = {"ode": 0}

    def integrate(self, task: IntegrationTask, trajectory: Trajectory) -> None:
        line = "x" * 1023 + "\n"
        half = NOISE_BYTES // 2 // len(line)
        print(FIRST_LINE)
        for _ in range(half):
            sys.stdout.write(line)
        sys.stdout.flush()
        block = (line * 1024).encode()
        for _ in range(half // 1024):
            os.write(2, block)
        os.write(2, (LAST_LINE + "\n").encode())

        def rhs(t, y):
            return task.form.rhs.into(t, y)[0].copy()

        times = task.times
        solution = scipy.integrate.solve_ivp(
            rhs, (times[0], times[-1]), task.y0, t_eval=times, rtol=task.rtol, atol=task.atol
        )
        trajectory.times, trajectory.y = solution.t, solution.y.T
        trajectory.stats.n_steps = max(1, (solution.nfev - 1) // 6)
        if not solution.success:
            trajectory.success, trajectory.message = False, solution.message


@integrator
class NoisyHang(Noisy):
    name = "test-noisy-hang"
    summary = "Says so on stderr, then never returns (test)"

    def integrate(self, task: IntegrationTask, trajectory: Trajectory) -> None:
        os.write(2, b"about to hang\n")
        while True:
            time.sleep(1.0)
