"""How many of example-robot-data's URDF files the workbench imports, beside Pinocchio.

Run: ``python -m benchmarks.robot_import_share [--no-dynamics]``. Prints a table (one row a
file, then the shares) and writes ``benchmarks/results/robot_import_share.csv``.

For every ``*.urdf`` of the installed example-robot-data: does ``pin.buildModelFromUrdf``
build it (mimic joints as independent joints, its default) and is its ``aba`` finite;
does ``load_urdf`` import it with its defaults, and with the options its one-line refusal
advises, which are also Pinocchio's reading: ``mimic="independent"``, ``meshes=False``
(Pinocchio does not need the meshes) and, for a file without a moving joint,
``floating_base=True``. Where both import, the recursive formalism's accelerations at one
random state are compared with ``pin.aba`` (``rel_diff``: max |ours - aba| / max |aba|),
so a file counts as read only if the dynamics agree too (to 1e-9); ``--no-dynamics``
skips that (a few seconds a file).
"""

from __future__ import annotations

import argparse
import contextlib
import io
import warnings
from importlib import metadata
from pathlib import Path

import numpy as np
import pandas as pd

from workbench.errors import ModelError
from workbench.model.importers.urdf import load_urdf

RESULTS = Path(__file__).parent / "results"
AGREE = 1e-9


def robots_folder() -> Path:
    distribution = metadata.distribution("example-robot-data")
    return Path(distribution.locate_file("cmeel.prefix/share/example-robot-data/robots"))


def quietly(function, *args, **kwargs):
    """Call ``function`` with stdout and stderr of Python captured (yourdfpy prints)."""
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        return function(*args, **kwargs)


def pinocchio_reads(path: Path) -> tuple[bool, str]:
    import pinocchio as pin

    try:
        quietly(pin.buildModelFromUrdf, str(path))
    except Exception as error:  # noqa: BLE001 - Pinocchio raises RuntimeError / ValueError
        return False, " ".join(str(error).split())[:160]
    return True, ""


def pinocchio_simulates(path: Path) -> bool:
    """``pin.aba`` is finite at the neutral configuration at rest (a massless link at the
    end of a chain makes the mass matrix singular: Pinocchio builds the model, but its
    accelerations are not numbers)."""
    import pinocchio as pin

    model = quietly(pin.buildModelFromUrdf, str(path))
    zero = np.zeros(model.nv)
    return bool(
        np.all(np.isfinite(pin.aba(model, model.createData(), pin.neutral(model), zero, zero)))
    )


def workbench_reads(path: Path, **options) -> tuple[object | None, str]:
    try:
        return quietly(load_urdf, path, **options), ""
    except ModelError as error:
        return None, str(error).replace(str(path.parent), "").lstrip("/")


def as_pinocchio(path: Path) -> tuple[object | None, str, str]:
    """The import with the options the refusals advise; (robot, options used, reason)."""
    options = {"mimic": "independent", "meshes": False}
    robot, reason = workbench_reads(path, **options)
    if robot is None and "no moving joint" in reason:
        options["floating_base"] = True
        robot, reason = workbench_reads(path, **options)
    used = ", ".join(f"{key}={value}" for key, value in options.items())
    return robot, used, reason


def aba_difference(robot) -> float:
    """max |ours - pin.aba| / max |pin.aba| at one random state, no torques."""
    import pinocchio as pin

    from tests.robot_peers import PinocchioMap, pinocchio_model, random_state
    from workbench.plugin.registry import get_formalism
    from workbench.testing.states import formalism_state

    peers = PinocchioMap(robot, quietly(pinocchio_model, robot))
    equations = get_formalism("recursive")().build(robot.model)
    q, v = random_state(peers.kinematics, np.random.default_rng(7))
    q_pin, v_pin, _ = peers.state(q, v)
    data = peers.pin_model.createData()
    expected = pin.aba(peers.pin_model, data, q_pin, v_pin, np.zeros(peers.pin_model.nv))
    ours = peers.accelerations(q, v, formalism_state(equations, 0.0, q, v).acceleration)
    return float(np.abs(ours - expected).max() / max(np.abs(expected).max(), 1e-300))


def measure(path: Path, root: Path, dynamics: bool) -> dict:
    row = {"file": str(path.relative_to(root))}
    row["pinocchio"], row["pinocchio_error"] = pinocchio_reads(path)
    row["pinocchio_aba_finite"] = row["pinocchio"] and pinocchio_simulates(path)
    default, _ = workbench_reads(path)
    row["workbench_default"] = default is not None
    robot, row["options"], row["workbench_error"] = as_pinocchio(path)
    row["workbench"] = robot is not None
    if robot is not None:
        from workbench.mechanics.kinematics import TreeKinematics

        row["nv"] = TreeKinematics(robot.model).nv
    if dynamics and robot is not None and row["pinocchio"]:
        try:
            row["rel_diff"] = aba_difference(robot)
        except Exception as error:  # noqa: BLE001 - a map this benchmark lacks: say so
            row["rel_diff"], row["workbench_error"] = float("nan"), f"not compared: {error}"
    return row


def main(argv: list[str] | None = None) -> pd.DataFrame:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--no-dynamics", action="store_true", help="imports only, no aba")
    arguments = parser.parse_args(argv)
    warnings.filterwarnings("ignore")
    root = robots_folder()
    files = sorted(root.rglob("*.urdf"))
    table = pd.DataFrame([measure(path, root, not arguments.no_dynamics) for path in files])
    RESULTS.mkdir(exist_ok=True)
    table.to_csv(RESULTS / "robot_import_share.csv", index=False)
    shown = table.drop(columns=["pinocchio_error"])
    with pd.option_context("display.width", 200, "display.max_rows", 500,
                           "display.max_colwidth", 90):  # fmt: skip
        print(shown.to_string(index=False, float_format=lambda x: f"{x:.2g}"))
    n = len(table)
    pin_ok = int(table["pinocchio"].sum())
    both = table["pinocchio"] & table["workbench"]
    print(f"\n{n} URDF files in example-robot-data {metadata.version('example-robot-data')}")
    finite = int(table["pinocchio_aba_finite"].sum())
    print(f"Pinocchio builds {pin_ok} ({pin_ok / n:.0%}); its aba is finite on {finite}")
    print(
        f"workbench imports {int(table['workbench_default'].sum())} with its defaults, "
        f"{int(table['workbench'].sum())} with the options its refusals advise "
        f"({table['workbench'].mean():.0%}); of Pinocchio's {pin_ok}: {int(both.sum())}"
    )
    if "rel_diff" in table:
        agree = int((table["rel_diff"] <= AGREE).sum())
        print(
            f"accelerations equal pin.aba to {AGREE:g} on {agree} of {int(both.sum())} "
            f"(worst {table['rel_diff'].max():.2g})"
        )
    return table


if __name__ == "__main__":
    main()
