"""A run scored against a reference computed with its own formalism says so in its notes:
its error then measures the integration only (the equations are the reference's own),
while another formalism's agreement with that reference is the independent check."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import workbench as wb
from tests.test_motionless import HANGING_ARM


def test_the_reference_s_own_formalism_is_named(tmp_path: Path) -> None:
    arm = tmp_path / "arm2.urdf"
    arm.write_text(HANGING_ARM)
    options = {"q0": {"shoulder": 0.6, "elbow": -0.3}, "t_end": 0.5}
    rows = {
        formalism: wb.run(str(arm), formalism, "scipy-dop853", rtol=1e-8, out=tmp_path / "out",
                          **options).row  # fmt: skip
        for formalism in ("recursive", "minimal-ode")
    }
    assert {row["status"] for row in rows.values()} == {"ok"}
    computed_with = rows["minimal-ode"]["reference"].removeprefix("computed: ").split(" + ")[0]
    own = "the reference was computed with this formalism"
    assert own in rows[computed_with]["notes"]
    other = next(name for name in rows if name != computed_with)
    assert own not in rows[other]["notes"]
    # a new process reads the reference from the folder's file: it knows the formalism too
    command = [sys.executable, "-m", "workbench", "run", str(arm), "-f", computed_with, "-i",
               "scipy-dop853", "--rtol", "1e-6", "-o", "q0={shoulder = 0.6, elbow = -0.3}",
               "-o", "t_end=0.5", "--out", str(tmp_path / "out")]  # fmt: skip
    done = subprocess.run(command, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    frame = wb.load_results(tmp_path / "out")
    (again,) = frame[frame["rtol"] == 1e-6].to_dict("records")
    assert "read from" in again["reference"] and own in again["notes"]
