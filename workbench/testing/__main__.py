"""``python -m workbench.testing KIND NAME [--plugins MODULE_OR_FILE] [--problems all|P1,P2]
[--structural] [--failures]``: run the conformance suite on one plugin and print its
report; exit code 1 on a failure, 2 on bad input.

NAME is a registered name, or ``MODULE_OR_FILE:Class``; ``--plugins`` (repeatable) imports
a plugin module first, as ``workbench run`` does: an installed module, or a module or
``.py`` file of the current directory such as ``workbench new`` writes without
``--package`` (``--no-local-plugins`` / ``WORKBENCH_NO_LOCAL_PLUGINS=1`` refuse those)."""

from __future__ import annotations

import argparse
import os
import sys

from workbench.errors import WorkbenchError
from workbench.plugin.local_modules import (
    NO_LOCAL_PLUGINS_VARIABLE,
    load_plugins,
)
from workbench.plugin.registry import REGISTRY, unregistered_hint
from workbench.testing import check_formalism, check_integrator, check_problem


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m workbench.testing", description=__doc__)
    parser.add_argument("kind", choices=["formalism", "integrator", "problem"])
    parser.add_argument("name", help="the registered plugin name, or MODULE_OR_FILE:Class")
    parser.add_argument(
        "--plugins",
        action="append",
        default=[],
        metavar="MODULE_OR_FILE",
        help="import this plugin module first (an installed module, or a module or .py file "
        "here; repeatable)",
    )
    parser.add_argument(
        "--no-local-plugins",
        action="store_true",
        help=f"import no local plugin module (also {NO_LOCAL_PLUGINS_VARIABLE}=1)",
    )
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
        allow_local = False if args.no_local_plugins else None  # None: the variable decides
        name = load_plugins(args.plugins, [args.name], allow_local)[1].get(args.name, args.name)
        _say_if_not_registered(args.kind, name)
        if args.kind == "formalism":
            report = check_formalism(name, problems, checks=checks)
        elif args.kind == "integrator":
            report = check_integrator(name, problems, checks=checks, progress=_progress)
        else:
            report = check_problem(name, checks=checks)
    except WorkbenchError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    shown = report.failures if args.failures else report.results
    try:
        print("\n".join([report.summary(), *(r.line() for r in shown)]), flush=True)
    except BrokenPipeError:  # `... | head` had what it wanted: end quietly (exit 1), as
        # `workbench` does (Click's way); stdout to /dev/null, so exit has nothing to flush
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 1
    return 0 if report.ok else 1


def _progress(line: str) -> None:
    """A check starting, on stderr: a hung plugin shows where it hangs."""
    print(line, file=sys.stderr, flush=True)


def _say_if_not_registered(kind: str, name: str) -> None:
    """A plugin module of the current directory (what ``workbench new`` writes without
    ``--package``) is not imported unless named: say how, rather than "unknown"."""
    REGISTRY.discover()
    if name in REGISTRY.entries[kind]:
        return
    hint = unregistered_hint(kind, name)  # its decorator forgotten, or no --plugins
    if hint:
        raise WorkbenchError(f"{kind} {name!r} is not registered; {hint}")


if __name__ == "__main__":
    sys.exit(main())
