"""Corpus making, benchmarks and flight tools: one package, each module run as ``python -m tools.NAME``
from the repository root (``--help`` on every one)."""
