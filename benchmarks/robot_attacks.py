"""Robot files as an attacker writes them (issue 31, items 1, 7, 8): every way a URDF or
MJCF file could make the workbench read outside its folder, read what is not a file, read
too much, or pass a non-finite number, plus meshes that cannot be read. A sibling of
``benchmarks/torture.py`` (whose security section covers results folders).

Run: ``python -m benchmarks.robot_attacks``. Each attack is a real file in a temporary
robot folder, imported through ``workbench.model.importers.load_robot`` (what ``run``,
``describe`` and every sweep worker call); unreadable meshes go through a real run with a
Rerun recording. Counted per attack: tries, refused with one line, read anyway (a hole),
tracebacks (an exception that is not a one-line WorkbenchError), outside bytes found in
what was produced. Prints a table and writes ``benchmarks/results/robot_attacks.csv``;
exit status 1 when a hole, a traceback or a leaked byte is counted.
"""

from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path

import pandas as pd

from benchmarks import help_if_asked
from workbench.errors import WorkbenchError
from workbench.model.importers import load_robot

RESULTS = Path(__file__).parent / "results"
SECRET = "SECRET-b7e2"
INERTIAL = '<inertial><mass value="1"/><inertia ixx="0.1" iyy="0.1" izz="0.1"/></inertial>'


def stl(name: str) -> str:
    return (
        f"solid {name}\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 0.1 0 0\n"
        f"vertex 0 0.1 0\nendloop\nendfacet\nendsolid {name}\n"
    )


def urdf(mesh: str) -> str:
    return f"""<robot name="r"><link name="base"/>
<link name="arm">{INERTIAL}<visual><geometry><mesh filename="{mesh}"/></geometry></visual></link>
<joint name="j" type="continuous"><parent link="base"/><child link="arm"/></joint></robot>"""


def mjcf(asset: str = "", compiler: str = "", body_extra: str = "", include: str = "") -> str:
    return f"""<mujoco model="r">{compiler}{include}<asset>{asset}</asset><worldbody>
<body name="b"><joint name="h" axis="0 0 1"/><geom size="0.1" {body_extra}/></body>
</worldbody></mujoco>"""


def urdf_meshes(outside: Path) -> list[str]:
    """Mesh references that lead outside the robot folder (or to what is not a file)."""
    return [
        "../outside/secret.stl",
        "../../../../../../../../etc/passwd",
        str(outside / "secret.stl"),
        "/etc/passwd",
        "/proc/self/environ",
        f"file://{outside / 'secret.stl'}",
        "file:///etc/passwd",
        "package://../outside/secret.stl",
        "package://robot/../outside/secret.stl",
        "package:///../../etc/passwd",
        "link-out.stl",  # a symbolic link in the robot folder to the secret
        "link-passwd.stl",  # ... to /etc/passwd
        "link-dir/secret.stl",  # a linked folder
        "http://example.com/mesh.stl",
    ]


def mjcf_files(outside: Path) -> list[str]:
    return [
        mjcf('<mesh name="m" file="../outside/secret.obj"/>'),
        mjcf(f'<mesh name="m" file="{outside / "secret.obj"}"/>'),
        mjcf('<mesh name="m" file="/etc/passwd"/>'),
        mjcf(f'<mesh name="m" file="file://{outside / "secret.obj"}"/>'),
        mjcf('<mesh name="m" file="secret.obj"/>', compiler=f'<compiler meshdir="{outside}"/>'),
        mjcf('<mesh name="m" file="secret.obj"/>', compiler='<compiler assetdir="../outside"/>'),
        mjcf('<texture name="t" type="2d" file="/etc/passwd"/>'),
        mjcf('<hfield name="h" file="../outside/secret.obj"/>'),
        mjcf(include='<include file="../outside/secret.xml"/>'),
        mjcf(include='<include file="/etc/passwd"/>'),
        mjcf('<mesh name="m" file="link-out.obj"/>'),
        mjcf('<mesh name="m" file="link-dir/secret.obj"/>'),
    ]


def not_files_or_too_big(robot: Path) -> list[tuple[str, str]]:
    """(file name, text) of robots naming a FIFO, a device, a folder, a file over 100 MB."""
    os.mkfifo(robot / "pipe.stl")
    (robot / "zero.stl").symlink_to("/dev/zero")
    (robot / "folder.stl").mkdir()
    with open(robot / "huge.stl", "wb") as huge:  # sparse: 101 MB on paper, none on disk
        huge.truncate(101_000_000)
    names = ["pipe.stl", "zero.stl", "folder.stl", "huge.stl"]
    return [("robot.urdf", urdf(name)) for name in names] + [
        ("scene.xml", mjcf(f'<mesh name="m" file="{name}"/>')) for name in names
    ]


NON_FINITE = [
    'mass="nan"', 'mass="inf"', 'mass="-inf"', 'mass="1e999"', 'pos="0 NaN 0"',
    'size="Infinity"', 'density="nan"', 'friction="1 nan 0"',
]  # fmt: skip


def attempt(robot: Path, name: str, text: str) -> str:
    """'refused' (one-line WorkbenchError), 'read' (imported) or 'traceback'."""
    (robot / name).write_text(text)
    try:
        load_robot(robot / name)
    except WorkbenchError as error:
        return "refused" if "\n" not in str(error) else "traceback"
    except Exception:  # noqa: BLE001 - counted: the CLI would print a traceback
        return "traceback"
    return "read"


def leaked(folder: Path) -> int:
    """Regular files under ``folder`` (links not followed) holding the secret."""
    return sum(
        SECRET.encode() in path.read_bytes()
        for path in folder.rglob("*")
        if path.is_file() and not path.is_symlink()
    )


def sweep_of_an_attack(base: Path, robot: Path) -> tuple[str, int]:
    """A real ``workbench sweep`` of a URDF whose mesh is a link out of its folder:
    ('refused' if its run failed with the refusal, else what happened; files under OUT
    holding the secret)."""
    import subprocess
    import sys

    from workbench.runs.store import load_results

    (robot / "robot.urdf").write_text(urdf("link-out.stl"))
    spec = base / "spec.toml"
    spec.write_text(
        'problems = [{ urdf = "robot/robot.urdf", t_end = 0.05 }]\nformalisms = ["recursive"]\n'
        'integrators = ["scipy-dop853"]\ntolerances = [1e-4]\nout = "OUT"\n'
    )
    command = [sys.executable, "-m", "workbench", "sweep", str(spec)]
    result = subprocess.run(command, cwd=base, capture_output=True, text=True, timeout=900)
    if "Traceback" in result.stderr:
        return "traceback", leaked(base / "OUT")
    (row,) = load_results(base / "OUT").to_dict("records")
    refused = row["status"] == "failed" and "outside" in row["message"]
    return ("refused" if refused else f"{row['status']}"), leaked(base / "OUT")


def box(base: Path) -> tuple[Path, Path]:
    robot, outside = base / "robot", base / "outside"
    robot.mkdir()
    outside.mkdir()
    (outside / "secret.stl").write_text(stl(SECRET))
    (outside / "secret.obj").write_text(f"# {SECRET}\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    (outside / "secret.xml").write_text(f"<mujoco><!-- {SECRET} --></mujoco>")
    (robot / "link-out.stl").symlink_to(outside / "secret.stl")
    (robot / "link-out.obj").symlink_to(outside / "secret.obj")
    (robot / "link-passwd.stl").symlink_to("/etc/passwd")
    (robot / "link-dir").symlink_to(outside)
    return robot, outside


def count(attack: str, outcomes: list[str], expected: str, happens: str) -> dict:
    return {
        "attack": attack,
        "tries": len(outcomes),
        "what happens": happens,
        "as expected": sum(outcome == expected for outcome in outcomes),
        "holes": sum(outcome not in (expected, "traceback") for outcome in outcomes),
        "tracebacks": outcomes.count("traceback"),
    }


def unreadable_meshes(base: Path) -> list[str]:
    """Runs of a robot whose mesh cannot be read: 'warned' when the run is ok with a
    warning naming the mesh (a placeholder is drawn), else what happened."""
    from workbench.execution.execute import RunSpec, execute_run, normalized_spec
    from workbench.outputs.recording import RerunSink

    meshes = {
        "corrupt.stl": b"solid x\nfacet nonsense\n" + bytes(range(256)),
        "picture.dae": b"\x89PNG\r\n\x1a\n" + bytes(64),
        "empty.obj": b"",
        "binary.glb": bytes(range(256)) * 4,
    }
    outcomes = []
    for name, data in meshes.items():
        folder = base / f"mesh-{name}"
        folder.mkdir()
        (folder / name).write_bytes(data)
        (folder / "robot.urdf").write_text(urdf(name))
        options = {"file": str(folder / "robot.urdf"), "t_end": 0.05}
        spec = normalized_spec(RunSpec("robot", "recursive", "scipy-dop853", 1e-6, 1e-9, options))
        row = execute_run(spec, sink=RerunSink()).row
        ok = row["status"] == "ok" and name in str(row.get("warnings", ""))
        outcomes.append("warned" if ok else f"{row['status']}: {row['message']}")
    return outcomes


ATTACKS = {
    # attack: (what it should be, what happens then)
    "URDF mesh leading out (../, absolute, file://, package://.., symlinks, http://)": (
        "refused", "refused: one line naming the link and where it leads"),
    "MJCF file leading out (mesh, texture, hfield, include, meshdir, assetdir, symlinks)": (
        "refused", "refused before MuJoCo compiles: one line naming the element"),
    "a FIFO, /dev/zero, a folder, a 101 MB file as a mesh (URDF, MJCF)": (
        "refused", "refused: not a regular file / over the 100 MB limit"),
    "MJCF non-finite number (nan, inf, 1e999, NaN in a vector)": (
        "refused", "refused: one line naming the element and the attribute"),
    "unreadable visual mesh (corrupt, wrong format, empty)": (
        "warned", "run ok, a warning in the row, a placeholder box drawn"),
    "workbench sweep of a URDF whose mesh links out of its folder": (
        "refused", "the run fails with the refusal; no file under OUT holds outside bytes"),
}  # fmt: skip


def main() -> int:
    with tempfile.TemporaryDirectory() as temporary:
        base = Path(temporary)
        robot, outside = box(base)
        sweep_outcome, secret_in = sweep_of_an_attack(base, robot)
        outcomes = [
            [attempt(robot, "robot.urdf", urdf(mesh)) for mesh in urdf_meshes(outside)],
            [attempt(robot, "scene.xml", text) for text in mjcf_files(outside)],
            [attempt(robot, name, text) for name, text in not_files_or_too_big(robot)],
            [attempt(robot, "scene.xml", mjcf(body_extra=value)) for value in NON_FINITE],
            unreadable_meshes(base),
            [sweep_outcome],
        ]
    rows = [
        count(attack, found, expected, happens)
        for (attack, (expected, happens)), found in zip(ATTACKS.items(), outcomes, strict=True)
    ]
    table = pd.DataFrame(rows)
    table["outside bytes in OUT"] = ["", "", "", "", "", str(secret_in)]
    RESULTS.mkdir(exist_ok=True)
    table.to_csv(RESULTS / "robot_attacks.csv", index=False)
    with pd.option_context("display.max_colwidth", 90, "display.width", 250):
        print(table.to_string(index=False))
    bad = int(table["holes"].sum() + table["tracebacks"].sum())
    return 1 if bad or secret_in else 0


if __name__ == "__main__":
    help_if_asked(__doc__, sys.argv[1:])
    raise SystemExit(main())
