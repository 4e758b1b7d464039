# %% [markdown]
# # First steps in Python
#
# The workbench as a library: run a catalog problem and plot its trajectory, define a
# problem of your own in the notebook and sweep it across three formalisms, then load the
# results and draw a work-precision diagram. Everything here is `workbench.run`,
# `workbench.sweep` and `workbench.load_results` (see the [API reference](../api.md)).

# %%
import tempfile

import matplotlib.pyplot as plt

import workbench as wb

wb.list_plugins("formalisms")[["name", "summary"]]

# %% [markdown]
# ## Run a catalog problem
#
# `describe` shows a problem's model; `run` runs it once, in this process, and returns a
# result: its row (every metric), the trajectory as a DataFrame with the equations' own
# names, and the drift, energy and error series.

# %%
wb.describe("double-pendulum")

# %%
result = wb.run("double-pendulum", "recursive", "sundials-cvode-bdf", rtol=1e-8)
result

# %%
result.trajectory.head()

# %%
fig, (left, right) = plt.subplots(1, 2, figsize=(11, 3.5))
result.plot(ax=left)
result.plot_energy(ax=right);

# %% [markdown]
# ## A problem of your own, defined here
#
# A mass on a spring, moving along a prismatic joint: its exact solution
# x(t) = x0 cos(ω t), ω = sqrt(k / m), is the reference every run is measured against. A
# class registered in the notebook has no module a worker process could import, so
# `sweep` runs it here, one run after another.

# %%
from dataclasses import dataclass

import numpy as np

from workbench.model import Model
from workbench.model.elements import JointSpringDamper
from workbench.plugin.problem import Problem, Reference
from workbench.plugin.registry import problem


@problem
class Oscillator(Problem):
    name = "notebook-oscillator"
    summary = "A mass on a spring along a prismatic joint (x0 = 0.1 m, omega = 5 rad/s)"
    t_end = 2.0
    n_samples = 81

    @dataclass(frozen=True)
    class Options:
        mass: float = 2.0  # kg
        stiffness: float = 50.0  # N/m

    def model(self):
        model = Model("notebook-oscillator", kind="planar")
        model.add_body("block", self.options.mass, inertia=0.01)
        model.add_joint("slide", "prismatic", "ground", "block", axis=(1, 0, 0))
        model.add_force(JointSpringDamper("spring", "slide", self.options.stiffness))
        return model

    def initial_joint_coordinates(self):
        return {"slide": 0.1}

    def reference(self):
        omega = np.sqrt(self.options.stiffness / self.options.mass)

        def poses(times):
            x = 0.1 * np.cos(omega * np.asarray(times))
            return np.stack([x, 0 * x, 0 * x, 1 + 0 * x, 0 * x, 0 * x, 0 * x], axis=1)[:, None]

        return Reference("analytic", poses, "x0 cos(omega t)")


# %%
out = tempfile.mkdtemp(prefix="first-steps-")
results = wb.sweep(
    problems=["notebook-oscillator"],
    formalisms=[{"name": f, "options": {"index": 1}}
                for f in ("minimal-ode", "recursive", "absolute-dae")],
    integrators=["scipy-dop853", "sundials-cvode-bdf"],
    tolerances=[1e-4, 1e-6, 1e-8],
    out=out,
)
results[["formalism", "integrator", "rtol", "status", "scd", "integrate_cpu_s"]]

# %% [markdown]
# ## Load the results and compare
#
# The results directory is the one `workbench sweep` writes: `load_results` reads its
# rows, `load_trajectory` a run's stored states.

# %%
results = wb.load_results(out)
wb.plot_work_precision(results, cost="n_rhs");

# %%
first = results.iloc[0]
wb.load_trajectory(out, first["run_id"]).head()
