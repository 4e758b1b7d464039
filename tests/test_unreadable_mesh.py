"""A visual mesh that cannot be read (corrupt, wrong format, empty) is a warning in the
run's row and a placeholder box in the recording, never a failed run (issue 31, item 7):
the dynamics do not depend on it. Before, the run failed at stage ``log``."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.test_recording import read_chunks
from workbench.execution.execute import RunSpec, execute_run, normalized_spec
from workbench.outputs.recording import RerunSink

pytest.importorskip("trimesh", reason="trimesh reads meshes (a dependency of yourdfpy)")

ROBOT = """<robot name="meshy"><link name="base"/>
<link name="arm"><inertial><origin xyz="0.1 0 0"/><mass value="1"/>
<inertia ixx="0.01" iyy="0.01" izz="0.01"/></inertial>
<visual><geometry><mesh filename="{mesh}"/></geometry></visual></link>
<joint name="j" type="continuous"><parent link="base"/><child link="arm"/>
<axis xyz="0 1 0"/></joint></robot>"""

BAD_MESHES = {
    # file name: bytes
    "corrupt.stl": b"solid broken\nfacet normal nonsense\n" + bytes(range(256)),
    "wrong-format.dae": b"\x89PNG\r\n\x1a\n" + bytes(64),  # a picture under a mesh's name
    "empty.obj": b"",
}


@pytest.mark.timeout(600)
@pytest.mark.parametrize("name", list(BAD_MESHES))
def test_an_unreadable_mesh_is_a_warning_and_a_placeholder(name: str, tmp_path: Path) -> None:
    (tmp_path / name).write_bytes(BAD_MESHES[name])
    (tmp_path / "robot.urdf").write_text(ROBOT.format(mesh=name))
    spec = normalized_spec(
        RunSpec(
            "robot", "recursive", "scipy-dop853", 1e-6, 1e-9,
            problem_options={"file": str(tmp_path / "robot.urdf"), "t_end": 0.1},
        )
    )  # fmt: skip
    sink = RerunSink()
    result = execute_run(spec, sink=sink)
    row = result.row
    assert row["status"] == "ok", row["message"]
    assert name in row["warnings"] and "cannot be read" in row["warnings"], row["warnings"]
    assert "\n" not in row["warnings"] and "drawn as a box" in row["warnings"]
    chunks = read_chunks(sink.save(tmp_path / "recording.rrd"))
    columns = {name for frames in chunks.values() for frame in frames for name in frame.columns}
    assert not any(name.startswith(("Asset3D:", "Mesh3D:")) for name in columns), columns
    # a red box where the mesh is, one of the run's boxes, labelled with its body
    (boxes,) = [path for path in chunks if path.endswith("/boxes")]
    (static,) = [frame for frame in chunks[boxes] if "sim_time" not in frame]
    assert "arm" in list(static["Boxes3D:labels"].iloc[0]), static
    assert "Boxes3D:colors" in static
