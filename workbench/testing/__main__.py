"""``python -m workbench.testing KIND NAME [--problems all|P1,P2] [--structural] [--failures]``:
run the conformance suite on one plugin and print its report; exit code 1 on a failure,
2 on bad input."""

from __future__ import annotations

import argparse
import sys

from workbench.errors import WorkbenchError
from workbench.testing import check_formalism, check_integrator, check_problem


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m workbench.testing", description=__doc__)
    parser.add_argument("kind", choices=["formalism", "integrator", "problem"])
    parser.add_argument("name", help="the registered plugin name")
    parser.add_argument(
        "--problems", help='"all" or a comma-separated list (default: a fast subset)'
    )
    parser.add_argument("--structural", action="store_true", help="only the structural checks")
    parser.add_argument("--failures", action="store_true", help="print only failed checks")
    args = parser.parse_args(argv)
    checks = "structural" if args.structural else "all"
    problems = args.problems
    if problems and problems != "all":
        problems = [p.strip() for p in problems.split(",") if p.strip()]
    try:
        if args.kind == "formalism":
            report = check_formalism(args.name, problems, checks=checks)
        elif args.kind == "integrator":
            report = check_integrator(args.name, problems, checks=checks)
        else:
            report = check_problem(args.name, checks=checks)
    except WorkbenchError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    shown = report.failures if args.failures else report.results
    print("\n".join([report.summary(), *(r.line() for r in shown)]))
    return 0 if report.ok else 1


if __name__ == "__main__":
    sys.exit(main())
