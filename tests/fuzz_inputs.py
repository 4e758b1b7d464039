"""Seeded generators of bad (and good) input for the fuzz tests of issue 18.

Sweep specifications as TOML text (valid ones, broken TOML, deep nesting, huge integers,
wrong types, duplicates, unknown keys, huge grids), mechanism models with NaN, inf and
wrong-typed parameters, and ``workbench run`` command lines. Plain NumPy RNGs with fixed
seeds: a failure names its case index and reproduces.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

PROBLEMS: list[Any] = [
    "simple-pendulum",
    "double-pendulum",
    "slider-crank",
    {"name": "planar-chain", "options": {"n_links": [2, 3]}},
    {"name": "simple-pendulum", "options": {"initial_angle": [0.1, 0.2]}},
]
FORMALISMS: list[Any] = [
    "minimal-ode",
    "recursive",
    "absolute-dae",
    {"name": "absolute-dae", "options": {"index": [1, 2]}},
    {"name": "all", "options": {"index": 1}},
]
INTEGRATORS: list[Any] = [
    "rk4",
    "scipy-rk45",
    "sundials-ida",
    {"name": "rk4", "options": {"step": [1e-3, 2e-3]}},
    {"name": "scipy-radau", "options": {"max_step": 0.1}},
]
WRONG_VALUES: list[Any] = [
    "x",
    "",
    0,
    -1,
    1.5,
    -0.0,
    math.inf,
    -math.inf,
    math.nan,
    True,
    [],
    {},
    [1, "a"],
    {"name": 3},
    {"name": "rk4", "options": 5},
    {"name": "rk4", "colour": "red"},
    [[1e-6]],
    "all",
]


def toml_value(value: Any) -> str:
    """``value`` as a TOML literal (inline tables for dicts)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return repr(value)
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, list):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{toml_key(k)} = {toml_value(v)}" for k, v in value.items()) + "}"
    if isinstance(value, _Raw):
        return value.text
    raise TypeError(type(value))


def toml_key(key: str) -> str:
    return key if key.replace("_", "").replace("-", "").isalnum() else toml_value(key)


class _Raw:
    """Literal TOML text (a huge integer, a deep nesting) placed as a value."""

    def __init__(self, text: str) -> None:
        self.text = text


def _pick(rng: np.random.Generator, items: list[Any], low: int = 1, high: int = 3) -> list[Any]:
    count = int(rng.integers(low, high + 1))
    chosen = rng.choice(len(items), size=min(count, len(items)), replace=False)
    return [items[int(i)] for i in chosen]


def _deep(rng: np.random.Generator) -> _Raw:
    depth = int(rng.choice([20, 100, 999, 3000, 20000]))
    if rng.random() < 0.5:
        return _Raw("[" * depth + "1" + "]" * depth)
    return _Raw("{a = " * depth + "1" + "}" * depth)


def _huge_int(rng: np.random.Generator) -> _Raw:
    digits = int(rng.choice([25, 400, 4299, 4301, 10000]))
    return _Raw(("-" if rng.random() < 0.3 else "") + "9" * digits)


def _big_grid(rng: np.random.Generator) -> dict[str, Any]:
    """A grid of one or two long axes (up to 20,000 x 20,000 combinations)."""
    length = int(rng.choice([10, 200, 2000, 20000]))
    axis = [1e-3 * (1 + i / 1e6) for i in range(length)]
    if rng.random() < 0.5:
        return {"name": "rk4", "options": {"step": axis}}
    return {"name": "scipy-rk45", "options": {"max_step": axis, "first_step": axis}}


def sweep_spec(seed: int) -> tuple[str, str]:
    """(TOML text, the mutation applied) of fuzz case ``seed``."""
    rng = np.random.default_rng([18, seed])
    data: dict[str, Any] = {
        "tolerances": sorted({float(10.0 ** -int(e)) for e in rng.integers(3, 10, size=2)}),
        "problems": _pick(rng, PROBLEMS),
        "formalisms": _pick(rng, FORMALISMS),
        "integrators": _pick(rng, INTEGRATORS),
    }
    if rng.random() < 0.3:
        data["jobs"] = int(rng.integers(1, 4))
    if rng.random() < 0.3:
        data["time_limit"] = float(rng.uniform(1, 100))
    if rng.random() < 0.2:
        data["atol_factor"] = 1e-2
    kind = str(
        rng.choice(
            [
                "valid",
                "wrong-type",
                "duplicate",
                "unknown-key",
                "deep",
                "huge-int",
                "big-grid",
                "broken-toml",
                "missing-key",
                "bad-plugin-module",
            ]
        )
    )
    key = str(
        rng.choice(
            [
                "tolerances",
                "problems",
                "formalisms",
                "integrators",
                "jobs",
                "time_limit",
                "atol_factor",
                "out",
                "missing_plugins",
            ]
        )
    )
    if kind == "wrong-type":
        data[key] = WRONG_VALUES[int(rng.integers(len(WRONG_VALUES)))]
    elif kind == "duplicate":
        where = int(rng.integers(4))
        if where == 0:
            data["tolerances"] = [1e-6, 1e-7, 1e-6]
        elif where == 1:
            data["integrators"] = ["rk4", {"name": "rk4", "options": {"step": 1e-3}}]
        elif where == 2:
            data["integrators"] = [{"name": "rk4", "options": {"step": [1e-3, 2e-3, 1e-3]}}]
        else:
            data["formalisms"] = [{"name": "absolute-dae", "options": {"index": [1, 1]}}]
    elif kind == "unknown-key":
        if rng.random() < 0.5:
            data[str(rng.choice(["tolerance", "problem", "speed", "jbos"]))] = 1
        else:
            data["integrators"] = [{"name": "rk4", "options": {"stepp": 1e-3}}]
    elif kind == "deep":
        target = str(rng.choice(["top", "options", "tolerances"]))
        if target == "top":
            data["problems"] = _deep(rng)
        elif target == "options":
            data["integrators"] = [{"name": "rk4", "options": {"step": _deep(rng)}}]
        else:
            data["tolerances"] = [_deep(rng)]
    elif kind == "huge-int":
        target = str(rng.choice(["jobs", "time_limit", "tolerances", "option"]))
        if target == "tolerances":
            data["tolerances"] = [_huge_int(rng)]
        elif target == "option":
            name = str(rng.choice(["step", "max_step"]))
            plugin = "rk4" if name == "step" else "scipy-rk45"
            data["integrators"] = [{"name": plugin, "options": {name: _huge_int(rng)}}]
        else:
            data[target] = _huge_int(rng)
    elif kind == "big-grid":
        if rng.random() < 0.5:
            data["integrators"] = [_big_grid(rng)]
        else:
            length = int(rng.choice([30, 100, 1000]))
            data["problems"] = [
                {
                    "name": "simple-pendulum",
                    "options": {"initial_angle": [0.1 + i * 1e-4 for i in range(length)]},
                }
            ]
            data["tolerances"] = [10.0 ** -(3 + i / 100) for i in range(int(rng.choice([5, 100])))]
            data["integrators"] = [
                {"name": "rk4", "options": {"step": [1e-3 * (1 + i / 1e4) for i in range(length)]}}
            ]
    elif kind == "missing-key":
        data.pop(str(rng.choice(["tolerances", "problems", "formalisms", "integrators"])))
    elif kind == "bad-plugin-module":
        data["plugins"] = ["no_such_module_for_fuzzing_" + str(seed)]
    text = "\n".join(f"{toml_key(k)} = {toml_value(v)}" for k, v in data.items()) + "\n"
    if kind == "broken-toml":
        cut = int(rng.integers(1, len(text)))
        junk = str(rng.choice(["", "[", "]]", "= =", '"', "{", "\x00", "é", "[[problems]]\n"]))
        text = text[:cut] + junk + text[cut + int(rng.integers(0, 5)) :]
    return text, kind


BAD_NUMBERS: list[Any] = [
    math.nan,
    math.inf,
    -math.inf,
    "1",
    "x",
    None,
    [1.0, 2.0],
    object(),
    1 + 2j,
    True,
]


def bad_value(rng: np.random.Generator, shape: tuple[int, ...] = ()) -> Any:
    """A wrong scalar, or an array of ``shape`` with one entry spoiled (or the wrong size)."""
    if not shape:
        return BAD_NUMBERS[int(rng.integers(len(BAD_NUMBERS)))]
    choice = int(rng.integers(5))
    if choice == 0:
        array = np.ones(shape).tolist()
        flat = array if len(shape) == 1 else array[int(rng.integers(shape[0]))]
        flat[int(rng.integers(len(flat)))] = float(rng.choice([math.nan, math.inf, -math.inf]))
        return array
    if choice == 1:
        return "abc"
    if choice == 2:
        return np.ones(int(rng.integers(1, 12))).tolist()
    if choice == 3:
        return [["x"] * 3] * 3 if len(shape) == 2 else ["x", 1, 2]
    return BAD_NUMBERS[int(rng.integers(len(BAD_NUMBERS)))]


MODEL_SLOTS = (
    "mass",
    "point-mass",
    "com",
    "inertia",
    "gravity",
    "frame-position",
    "frame-rotation",
    "joint-frame",
    "axis",
    "stiffness",
    "rest",
    "initial-q",
    "initial-v",
)


def model_case(seed: int) -> tuple[str, str, Any]:
    """(slot, the element its ModelError must name, a bad value) of model fuzz case ``seed``."""
    rng = np.random.default_rng([5, seed])
    slot = MODEL_SLOTS[seed % len(MODEL_SLOTS)]
    shape = {
        "com": (3,),
        "inertia": (3, 3) if rng.random() < 0.5 else (3,),
        "gravity": (3,),
        "frame-position": (3,),
        "frame-rotation": (3, 3),
        "axis": (3,),
        "initial-q": (1,),
        "initial-v": (1,),
    }.get(slot, ())
    value = bad_value(rng, shape)
    element = {
        "mass": "body 'link'",
        "point-mass": "body 'bob'",
        "com": "body 'link'",
        "inertia": "body 'link'",
        "gravity": "gravity",
        "frame-position": "frame",
        "frame-rotation": "frame",
        "joint-frame": "joint 'hinge'",
        "axis": "joint 'hinge'",
        "stiffness": "force 'spring'",
        "rest": "force 'spring'",
        "initial-q": "joint 'hinge'",
        "initial-v": "joint 'hinge'",
    }[slot]
    return slot, element, value


RUN_NUMBERS = [
    "1e-6",
    "1e-3",
    "0.5",
    "inf",
    "-inf",
    "nan",
    "2",
    "1",
    "0",
    "-1e-6",
    "1e400",
    "abc",
    "",
    "9" * 5000,
]
RUN_OPTIONS = [
    "step=1e-3",
    "step=1e-300",
    "step=-1",
    "step=inf",
    "step=nan",
    "step=abc",
    "step=" + "9" * 5000,
    "step=[1, 2]",
    "index=1",
    "index=7",
    "formalism.index=2",
    "integrator.step=2e-3",
    "problem.initial_angle=0.3",
    "problem.initial_angle=x",
    "nonsense=1",
    "=",
    "x",
    "planet.step=1",
    "max_step=1e-300",
    "max_step=0.1",
]
RUN_PLUGINS = [
    ("simple-pendulum", "minimal-ode", "rk4"),
    ("simple-pendulum", "minimal-ode", "scipy-rk45"),
    ("double-pendulum", "recursive", "rk4"),
    ("simple-pendelum", "minimal-ode", "rk4"),
    ("simple-pendulum", "minimal", "rk4"),
    ("simple-pendulum", "minimal-ode", "rk5"),
]


def run_command(seed: int) -> list[str]:
    """The arguments of ``workbench run`` fuzz case ``seed``."""
    rng = np.random.default_rng([8, seed])
    problem, formalism, integrator = RUN_PLUGINS[int(rng.integers(len(RUN_PLUGINS)))]
    args = ["run", problem, "-f", formalism, "-i", integrator]
    for flag in ("--rtol", "--atol", "--time-limit"):
        if rng.random() < 0.5:
            args += [flag, RUN_NUMBERS[int(rng.integers(len(RUN_NUMBERS)))]]
    for _ in range(int(rng.integers(0, 3))):
        args += ["-o", RUN_OPTIONS[int(rng.integers(len(RUN_OPTIONS)))]]
    return args


def build_model(slot: str, value):
    """A planar two-body pendulum with ``value`` put in ``slot``; validated, initial state read."""
    from workbench.mechanics.kinematics import TreeKinematics, initial_joint_values
    from workbench.model import Frame, JointSpringDamper, Model

    def pick(name, good):
        return value if slot == name else good

    model = Model("fuzz", "spatial", gravity=pick("gravity", (0.0, 0.0, -9.81)))
    model.add_body(
        "link",
        pick("mass", 1.0),
        com=pick("com", (0.5, 0.0, 0.0)),
        inertia=pick("inertia", (0.01, 0.1, 0.1)),
    )
    model.add_point_mass("bob", pick("point-mass", 0.5))
    if slot == "frame-position":
        frame = Frame(position=value)
    elif slot == "frame-rotation":
        frame = Frame(rotation=value)
    else:
        frame = pick("joint-frame", Frame.at(0.0, 0.0, 0.0))
    model.add_joint(
        "hinge",
        "revolute",
        "ground",
        "link",
        parent_frame=frame,
        axis=pick("axis", (0.0, 1.0, 0.0)),
    )
    model.add_joint(
        "rod",
        "prismatic",
        "link",
        "bob",
        parent_frame=Frame.at(1.0, 0.0, 0.0),
        axis=(1.0, 0.0, 0.0),
    )
    model.add_force(
        JointSpringDamper("spring", "hinge", pick("stiffness", 1.0), rest=pick("rest", 0.0))
    )
    model.validate()
    kinematics = TreeKinematics(model)
    initial_joint_values(model, kinematics, {"hinge": pick("initial-q", 0.1)}, False)
    initial_joint_values(model, kinematics, {"hinge": pick("initial-v", 0.0)}, True)
    return model
