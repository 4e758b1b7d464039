"""execution: one run, executed and measured (docs/architecture.md, "The layers")."""
