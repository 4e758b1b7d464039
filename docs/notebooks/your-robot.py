# %% [markdown]
# # Benchmark your own robot
#
# A robot file (URDF, or MuJoCo's MJCF) is a problem: the workbench imports it, checks
# it and runs it unforced under gravity from its initial pose. Here the RSSR linkage
# shipped with the workbench (`problems/robot_files/rssr_linkage.xml`), a spatial
# closed chain; put the path of your own file in its place.

# %%
import tempfile
from importlib.resources import files

import matplotlib.pyplot as plt

import workbench as wb

robot = str(files("workbench.problems") / "robot_files" / "rssr_linkage.xml")
wb.describe(robot)

# %% [markdown]
# One run first. Its reference is computed at run time by two independent pipelines
# (no analytic or stored one exists for your file) and kept in `out/references`, so the
# sweep below reuses it. The option `t_end` shortens the problem to keep this quick.

# %%
out = tempfile.mkdtemp(prefix="your-robot-")
result = wb.run(robot, "recursive", "sundials-ida", rtol=1e-6, index=1,
                t_end=0.5, n_samples=51, out=out)
result

# %% [markdown]
# The loop closure holds through the multipliers: the trajectory carries them, named by
# the closing joint, and the drift series says how well the constraints held.

# %%
fig, (left, right) = plt.subplots(1, 2, figsize=(11, 3.5))
result.plot(["crank_joint", "rocker_joint"], ax=left)
result.plot_drift(ax=right);

# %%
result.trajectory.filter(like="lambda:").describe().loc[["min", "max"]]

# %% [markdown]
# ## Which formalism and integrator for this robot?
#
# The same file in a sweep: two formalisms, two integrators, three tolerances. A sweep
# entry `{"mjcf": path}` (or `{"urdf": path}`) names a robot file, as in a TOML
# specification.

# %%
results = wb.sweep(
    problems=[{"mjcf": robot, "t_end": 0.5, "n_samples": 51}],
    formalisms=[{"name": f, "options": {"index": 1}} for f in ("recursive", "absolute-dae")],
    integrators=["sundials-ida", "sundials-cvode-bdf"],
    tolerances=[1e-4, 1e-6, 1e-8],
    out=out,
    jobs=2,
)
results[["formalism", "integrator", "rtol", "status", "scd", "drift_pos_max", "n_rhs"]]

# %%
wb.plot_work_precision(results, cost="n_rhs");
