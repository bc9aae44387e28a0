"""The matplotlib entry point of every diffship figure: non-display for the command lines, inline in notebooks.

The command lines write figures to files and must not need a display, so they switch matplotlib to its
Agg backend; a notebook's inline (or widget) backend is kept, so that a notebook calling the same
plotting functions draws the figures (a report function that switched the backend made a notebook draw nothing). Plain Python: matplotlib is imported only when a figure is made.
"""

from __future__ import annotations

__all__ = ["pyplot"]

_KEEP = ("inline", "ipympl", "widget", "nbagg")


def pyplot():
    """``matplotlib.pyplot``, with the Agg backend unless a notebook backend is active."""
    import matplotlib

    backend = str(matplotlib.rcParams.get("backend", "")).lower()
    if not any(k in backend for k in _KEEP):
        matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt
