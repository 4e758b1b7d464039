"""How the model checks scale with the number of links (issue 31, item 6): a serial
chain of revolute links, built in Python and read from a URDF.

Run: ``python -m benchmarks.long_chain [--links 150,600,1000,3000,10000]``. For each
length: seconds (CPU time of this process, which is what scales; wall time on a loaded
machine is larger) to build the model, validate it, analyse its topology (DOF by rank,
as ``workbench describe`` and every formalism do) and import the URDF (yourdfpy reading
included). The seconds per link stay flat when a step is O(n). Prints a table and writes
``benchmarks/results/long_chain.csv``.

Before this change (issue 31): validation 0.01 / 0.09 / 0.81 s at 150 / 300 / 600 links
(O(n^3)), ``analyze`` 5.5 s at 1,000 links and 13 s at 2,000, a 5,000-link URDF's
``describe`` never finished.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import pandas as pd

from workbench.mechanics.topology import analyze
from workbench.model.importers import load_robot

RESULTS = Path(__file__).parent / "results"


def cpu_seconds(step) -> tuple[float, object]:
    start = time.process_time()
    result = step()
    return time.process_time() - start, result


def measure(links: int, folder: Path) -> dict:
    from tests.test_long_chain import chain, chain_urdf

    build_s, model = cpu_seconds(lambda: chain(links))
    validate_s, _ = cpu_seconds(model.validate)
    analyze_s, topology = cpu_seconds(lambda: analyze(model))
    path = folder / f"chain{links}.urdf"
    path.write_text(chain_urdf(links))
    import_s, imported = cpu_seconds(lambda: load_robot(path))
    assert topology.dof == links and len(imported.model.bodies) == links
    return {
        "links": links,
        "build_s": build_s,
        "validate_s": validate_s,
        "analyze_s": analyze_s,
        "urdf_import_s": import_s,
        "validate_us_per_link": 1e6 * validate_s / links,
        "analyze_us_per_link": 1e6 * analyze_s / links,
        "urdf_import_us_per_link": 1e6 * import_s / links,
        "load1": os.getloadavg()[0],
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--links", default="150,600,1000,3000,10000")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as folder:
        rows = [measure(int(n), Path(folder)) for n in args.links.split(",")]
    table = pd.DataFrame(rows)
    RESULTS.mkdir(exist_ok=True)
    table.to_csv(RESULTS / "long_chain.csv", index=False)
    print(table.to_string(index=False, float_format=lambda x: f"{x:.3g}"))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
