"""Performance benchmarks (not tests): each prints a table and writes a CSV to results/."""
