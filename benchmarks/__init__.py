"""Performance benchmarks (not tests): each prints a table and writes a CSV to results/."""


def help_if_asked(doc: str | None, argv: list[str]) -> None:
    """For a benchmark that reads its arguments by hand: ``-h`` / ``--help`` prints its
    module docstring (how to run it) and exits, instead of failing or starting a run."""
    import sys

    if {"-h", "--help"} & set(argv):
        print((doc or "").strip())
        sys.exit(0)
