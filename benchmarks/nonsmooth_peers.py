"""Peer check of the contact problems against MuJoCo's soft contacts, its softness stated.

Run: ``python -m benchmarks.nonsmooth_peers``. Prints a table and writes
``benchmarks/results/nonsmooth_peers.csv``: for the bouncing ball, the block that slides
down and the block that stops on the incline, and the sliding sphere, the quantities the
analytic references state (impact times, rebound height, sliding acceleration, stick time,
rolling time and speed) as MuJoCo measures them and as our three contact integrators do
(minimal-ode formalism; event-driven and compliant-contact at rtol 1e-8, Moreau-Jean with
a 1e-4 s step, compliant-contact with k = 1e6 N/m), each beside the analytic value.

MuJoCo's contact is soft (Todorov 2014; the "Computation" chapter of its documentation):
each constraint row obeys ``a1 + d (b v + k r) = (1 - d) a0`` with the impedance d (solimp;
here constant: dmin = dmax = D), b = 2 / (dmax tau), k = d / (dmax^2 tau^2 zeta^2) (solref
= (tau, zeta)). With d = dmax the violation r of a contact is a linear spring-damper of
natural frequency 1 / (tau zeta) and damping ratio zeta, driven by (1 - d) a0. Hence:

* a body at rest sinks to r = (1 - d) g_n tau^2 zeta^2 (g_n: gravity along the normal);
* an impact rebounds with the restitution of that spring-damper,
  e = exp(-zeta pi / sqrt(1 - zeta^2)): we choose zeta from the problem's e (the same rule
  as our compliant contact) and the impact lasts about pi tau zeta;
* friction rows have no position (r = 0): a contact that should stick creeps at
  v = (1 - d) a_t tau / 2 where a_t is the tangential acceleration it holds back.

The settings (``SOFTNESS``): timestep 1e-4 s (tau / 200), Euler integrator (MuJoCo's
semi-implicit default), elliptic friction cones, impratio 1, condim 1 (frictionless ball)
or 3, tau = 0.02 s (MuJoCo's default), D = 0.99. The incline is MuJoCo's floor z = 0 under
gravity tilted by 30 degrees (the same dynamics as a tilted plane). Project Chrono's Python
bindings are not on PyPI (the ``pychrono`` there is an unrelated timing package; Chrono
ships through conda), so MuJoCo is the only peer.
"""

from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from benchmarks import help_if_asked
from workbench.equations.initial import consistent_initial_state
from workbench.plugin import registry
from workbench.problems.ch5_contacts import (
    BALL_DROP,
    BALL_RADIUS,
    BALL_RESTITUTION,
    BLOCK_HALF_HEIGHT,
    BLOCK_HALF_LENGTH,
    BLOCK_MASS,
    GRAVITY,
    INCLINE,
    SPHERE_FRICTION,
    SPHERE_MASS,
    SPHERE_RADIUS,
    SPHERE_SPEED,
    bouncing_ball_impacts,
)

RESULTS = Path(__file__).parent / "results"


@dataclass(frozen=True)
class Softness:
    """MuJoCo's contact settings, stated in every row."""

    timestep: float = 1e-4  # s
    timeconst: float = 0.02  # s, solref[0]
    impedance: float = 0.99  # solimp dmin = dmax
    integrator: str = "Euler"
    cone: str = "elliptic"
    impratio: float = 1.0

    def dampratio(self, restitution: float) -> float:
        """solref[1]: the damping ratio whose spring-damper rebounds with ``restitution``."""
        if restitution <= 0:
            return 1.0
        log_e = math.log(restitution)
        return -log_e / math.sqrt(math.pi**2 + log_e**2)

    def rest_penetration(self, normal_gravity: float, restitution: float) -> float:
        """(1 - d) g_n tau^2 zeta^2: the depth a body at rest sinks to (module docstring)."""
        zeta = self.dampratio(restitution)
        return (1 - self.impedance) * normal_gravity * (self.timeconst * zeta) ** 2

    def creep_speed(self, tangential: float) -> float:
        """(1 - d) a_t tau / 2: the speed at which a contact that should stick slides."""
        return (1 - self.impedance) * tangential * self.timeconst / 2

    def label(self, restitution: float) -> str:
        return (f"solref=({self.timeconst:g}, {self.dampratio(restitution):.4g}) "
                f"solimp=({self.impedance:g}, {self.impedance:g}) dt={self.timestep:g} "
                f"{self.integrator} {self.cone} impratio={self.impratio:g}")  # fmt: skip


SOFTNESS = Softness()


def mjcf(problem: str, softness: Softness = SOFTNESS) -> str:
    """The MJCF of one contact problem (z up; the incline as tilted gravity)."""
    e = BALL_RESTITUTION if problem == "bouncing-ball" else 0.0
    zeta = softness.dampratio(e)
    d = softness.impedance
    gravity = (0.0, 0.0, -GRAVITY)
    if problem.startswith("incline"):
        gravity = (GRAVITY * math.sin(INCLINE), 0.0, -GRAVITY * math.cos(INCLINE))
    mu = {"bouncing-ball": 0.0, "incline-block-slide": 0.3, "incline-block-stop": 0.8,
          "sliding-sphere": SPHERE_FRICTION}[problem]  # fmt: skip
    condim = 1 if mu == 0 else 3
    if problem == "bouncing-ball":
        body = (f'<body name="ball" pos="0 0 {BALL_DROP + BALL_RADIUS}"><freejoint/>'
                f'<geom type="sphere" size="{BALL_RADIUS}" mass="1"/></body>')  # fmt: skip
    elif problem == "sliding-sphere":
        body = (
            f'<body name="sphere" pos="0 0 {SPHERE_RADIUS}"><freejoint/>'
            f'<geom type="sphere" size="{SPHERE_RADIUS}" mass="{SPHERE_MASS}"/></body>'
        )
    else:
        size = f"{BLOCK_HALF_LENGTH} 0.05 {BLOCK_HALF_HEIGHT}"
        body = (f'<body name="block" pos="0 0 {BLOCK_HALF_HEIGHT}"><freejoint/>'
                f'<geom type="box" size="{size}" mass="{BLOCK_MASS}"/></body>')  # fmt: skip
    return f"""<mujoco model="{problem}">
  <option timestep="{softness.timestep}" gravity="{" ".join(map(str, gravity))}"
          integrator="{softness.integrator}" cone="{softness.cone}" impratio="{softness.impratio}"/>
  <default><geom condim="{condim}" friction="{mu} 0 0" solref="{softness.timeconst} {zeta}"
                 solimp="{d} {d} 0.001 0.5 2"/></default>
  <worldbody><geom name="floor" type="plane" size="0 0 1"/>{body}</worldbody>
</mujoco>"""


@dataclass
class Motion:
    """A run's motion along the floor: times, the body's height above its resting height
    (z), its distance along x (s) and speed (u), the slip speed of the contact point,
    contact starts (impacts), the friction's ratio to its cone's edge, the deepest
    penetration, the CPU seconds."""

    times: np.ndarray
    z: np.ndarray
    s: np.ndarray
    u: np.ndarray
    w: np.ndarray  # vertical speed
    slip: np.ndarray
    impacts: list[float]
    cone_ratio: np.ndarray
    penetration: float
    cpu_s: float
    sticks: list[float]


def mujoco_motion(problem: str, t_end: float, softness: Softness = SOFTNESS) -> Motion:
    """Step MuJoCo's model of ``problem`` to ``t_end``, recording every step."""
    import mujoco

    model = mujoco.MjModel.from_xml_string(mjcf(problem, softness))
    data = mujoco.MjData(model)
    radius = SPHERE_RADIUS if problem == "sliding-sphere" else 0.0
    rest = BALL_RADIUS if problem == "bouncing-ball" else (radius or BLOCK_HALF_HEIGHT)
    if problem == "incline-block-stop":
        data.qvel[0] = 2.0
    if problem == "sliding-sphere":
        data.qvel[0] = SPHERE_SPEED
    mujoco.mj_forward(model, data)
    n = int(round(t_end / softness.timestep))
    out = np.empty((n + 1, 7))
    impacts, force = [], np.zeros(6)
    touching, penetration = False, 0.0
    start = time.process_time()
    for k in range(n + 1):
        normal = tangent = 0.0
        for i in range(data.ncon):
            mujoco.mj_contactForce(model, data, i, force)
            normal += force[0]
            tangent += math.hypot(force[1], force[2])
            penetration = max(penetration, -float(data.contact[i].dist))
        if data.ncon and not touching:
            impacts.append(float(data.time))
        touching = data.ncon > 0
        mu = float(model.geom_friction[0, 0])
        ratio = tangent / (mu * normal) if mu > 0 and normal > 0 else math.nan
        # the contact point's speed along x: u - omega_y r (a free joint's qvel[3:6] is
        # the angular velocity in the body frame: rotated to the world's)
        omega = np.zeros(3)
        mujoco.mju_rotVecQuat(omega, data.qvel[3:6], data.qpos[3:7])
        slip = data.qvel[0] - omega[1] * radius
        out[k] = (data.time, data.qpos[2] - rest, data.qpos[0], data.qvel[0], data.qvel[2],
                  slip, ratio)  # fmt: skip
        if k < n:
            mujoco.mj_step(model, data)
    cpu = time.process_time() - start
    ratio = out[:, 6]
    # stick: the first step after the start whose friction leaves the cone's edge (99 %)
    sliding = np.flatnonzero(ratio > 0.99)
    sticks = []
    if sliding.size:
        after = np.flatnonzero((np.arange(ratio.size) > sliding[0]) & (ratio < 0.99))
        if after.size:
            sticks.append(float(out[after[0], 0]))
    return Motion(out[:, 0], out[:, 1], out[:, 2] - out[0, 2], out[:, 3], out[:, 4],
                  out[:, 5], impacts, ratio, penetration, cpu, sticks)  # fmt: skip


def our_motion(problem_name: str, integrator: str, options: dict, rtol: float) -> Motion:
    """Run our ``integrator`` (minimal-ode) on ``problem_name``, in MuJoCo's axes."""
    problem = registry.get_problem(problem_name)()
    equations = registry.get_formalism("minimal-ode")().build(problem.model())
    times = problem.sample_times()
    y0 = consistent_initial_state(equations, problem).y0(equations, "mechanical")
    method = registry.get_integrator(integrator)()
    start = time.process_time()
    trajectory = method.solve(equations, y0, None, times, rtol, rtol * 1e-3, options or None)
    cpu = time.process_time() - start
    if not trajectory.success:
        raise RuntimeError(f"{integrator} on {problem_name}: {trajectory.message}")
    poses = np.stack([equations.observables.poses(t, y[: equations.nq])[0]
                      for t, y in zip(trajectory.times, trajectory.y, strict=True)])  # fmt: skip
    t = trajectory.times
    position = poses[:, :3]
    if problem_name.startswith("incline"):  # along the slope, downwards; and off it
        down = -np.array([math.cos(INCLINE), math.sin(INCLINE), 0.0])
        normal = np.array([-math.sin(INCLINE), math.cos(INCLINE), 0.0])
        s, z = (position - position[0]) @ down, position @ normal - BLOCK_HALF_HEIGHT
    elif problem_name == "bouncing-ball":
        s, z = position[:, 0] - position[0, 0], position[:, 1] - BALL_RADIUS
    else:
        s, z = position[:, 0] - position[0, 0], position[:, 2] - SPHERE_RADIUS
    u, w = np.gradient(s, t), np.gradient(z, t)
    if problem_name == "bouncing-ball":  # the vertical speed is a state: no differencing
        w = trajectory.y[:, equations.nq + 1]
    events = list(trajectory.contact.get("event_times", []))
    impacts = events if problem_name == "bouncing-ball" else []
    # stick events: event-driven's and Moreau-Jean's; the compliant contact's events are
    # closings (it never sticks: it creeps)
    sticks = [] if problem_name == "bouncing-ball" or integrator == "compliant-contact" else events
    return Motion(
        t,
        z,
        s,
        u,
        w,
        np.full(t.size, np.nan),
        impacts,
        np.full(t.size, np.nan),
        float(trajectory.contact.get("penetration_max", np.nan)),
        cpu,
        sticks,
    )


def nearest(events: list[float], time: float) -> float:
    """The run's event nearest the reference's (as the row's event_time_err_max pairs them)."""
    return min(events, key=lambda event: abs(event - time)) if events else math.nan


def quantities(problem: str, motion: Motion) -> dict[str, float]:
    """What the analytic reference states, measured from ``motion``."""
    t = motion.times
    reference = analytic(problem)
    if problem == "bouncing-ball":
        impacts = [*motion.impacts, math.nan, math.nan][:2]
        flight = (t > impacts[0] + 0.05) & (t < (impacts[1] if impacts[1] == impacts[1]
                                                  else t[-1]) - 0.05)  # fmt: skip
        # the apex from the flight's energy per unit mass g z + w^2 / 2 (exact in free flight)
        apex = float(np.median(motion.z[flight] + motion.w[flight] ** 2 / (2 * GRAVITY)))
        return {"impact_1_s": impacts[0], "impact_2_s": impacts[1], "apex_1_m": apex,
                "penetration_max_m": motion.penetration}  # fmt: skip
    if problem == "incline-block-slide":
        late = t >= 1.0
        slope = np.polyfit(t[late], motion.s[late], 2)[0] * 2
        return {"slide_accel_m_s2": float(slope), "s_end_m": float(motion.s[-1]),
                "penetration_max_m": motion.penetration}  # fmt: skip
    if problem == "incline-block-stop":
        late = t >= 1.5
        creep = float(np.polyfit(t[late], motion.s[late], 1)[0])
        return {"stick_time_s": nearest(motion.sticks, reference["stick_time_s"]),
                "s_end_m": float(motion.s[-1]), "creep_speed_m_s": creep,
                "penetration_max_m": motion.penetration}  # fmt: skip
    late = t >= 0.8
    speed = float(np.polyfit(t[late], motion.s[late], 1)[0])
    return {"roll_time_s": nearest(motion.sticks, reference["roll_time_s"]),
            "roll_speed_m_s": speed, "s_end_m": float(motion.s[-1]),
            "penetration_max_m": motion.penetration}  # fmt: skip


def analytic(problem_name: str) -> dict[str, float]:
    """The reference values of :func:`quantities`."""
    problem = registry.get_problem(problem_name)()
    if problem_name == "bouncing-ball":
        impacts = bouncing_ball_impacts(problem.t_end, BALL_DROP, BALL_RESTITUTION)
        return {
            "impact_1_s": impacts[0],
            "impact_2_s": impacts[1],
            "apex_1_m": BALL_DROP * BALL_RESTITUTION**2,
            "penetration_max_m": 0.0,
        }
    if problem_name.startswith("incline"):
        end = float(problem.slope_distance(np.array([problem.t_end]))[0])
        values = {"s_end_m": end, "penetration_max_m": 0.0}
        if problem_name.endswith("slide"):
            accel = GRAVITY * (math.sin(INCLINE) - 0.3 * math.cos(INCLINE))
            return {"slide_accel_m_s2": accel, **values}
        stick = float(problem.contact_events()[0])
        return {"stick_time_s": stick, "creep_speed_m_s": 0.0, **values}
    x, _, _, _ = problem.motion(np.array([problem.t_end]))
    return {
        "roll_time_s": problem.roll_time(),
        "roll_speed_m_s": 5 / 7 * SPHERE_SPEED,
        "s_end_m": float(x[0]),
        "penetration_max_m": 0.0,
    }


OURS = [  # integrator, options, rtol
    ("event-driven", {}, 1e-8),
    ("moreau-jean", {"step": 1e-4}, 1e-8),
    ("compliant-contact", {"stiffness": 1e6}, 1e-8),
]
PROBLEMS = ["bouncing-ball", "incline-block-slide", "incline-block-stop", "sliding-sphere"]


def measure(problems: list[str] = PROBLEMS) -> pd.DataFrame:
    rows = []
    for name in problems:
        reference = analytic(name)
        t_end = registry.get_problem(name)().t_end
        e = BALL_RESTITUTION if name == "bouncing-ball" else 0.0
        runs = [("mujoco", SOFTNESS.label(e), lambda n=name, t=t_end: mujoco_motion(n, t))]
        for integrator, options, rtol in OURS:
            label = f"minimal-ode rtol={rtol:g} {options}"
            runs.append(
                (
                    integrator,
                    label,
                    lambda n=name, i=integrator, o=options, r=rtol: our_motion(n, i, o, r),
                )
            )
        for method, settings, run in runs:
            try:
                motion = run()
            except Exception as error:  # noqa: BLE001 - a refused pairing is a row
                rows.append(
                    {
                        "problem": name,
                        "method": method,
                        "settings": settings,
                        "quantity": "-",
                        "note": str(error).splitlines()[0],
                    }
                )
                continue
            for quantity, value in quantities(name, motion).items():
                expected = reference.get(quantity, math.nan)
                rows.append({"problem": name, "method": method, "settings": settings,
                             "quantity": quantity, "value": value, "analytic": expected,
                             "error": value - expected, "cpu_s": motion.cpu_s})  # fmt: skip
    return pd.DataFrame(rows)


def main() -> None:
    table = measure(sys.argv[1:] or PROBLEMS)
    RESULTS.mkdir(exist_ok=True)
    table.to_csv(RESULTS / "nonsmooth_peers.csv", index=False)
    with pd.option_context("display.width", 200, "display.max_colwidth", 60):
        print(
            table.drop(columns=["settings", "note"], errors="ignore").to_string(
                index=False, float_format="%.4g", na_rep="-"
            )
        )
        for (method, settings), _ in table.groupby(["method", "settings"], sort=False):
            print(f"{method}: {settings}")
        for _, row in table[table["quantity"] == "-"].iterrows():
            print(f"{row['problem']} / {row['method']}: {row['note']}")


if __name__ == "__main__":
    help_if_asked(__doc__, sys.argv[1:])
    main()
