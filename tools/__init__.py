"""Corpus making, benchmarks and flight tools, in four groups by what they serve: speech, listen, flight, sim.
Each command runs as ``python -m tools.GROUP.NAME`` from the repository root (``--help`` on every one);
``python -m tools`` lists them, one line each (tools/README.md has the same index)."""
