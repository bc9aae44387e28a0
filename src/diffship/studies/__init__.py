"""Worked studies on real data that notebooks and benchmarks share (one module per study)."""
