"""runs: sweeps of many runs (docs/architecture.md, "The layers")."""
