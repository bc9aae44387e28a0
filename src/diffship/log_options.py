"""Command-line options shared by every command that reads runs or writes a report: ``--map`` and ``--html``.

Plain Python (the fit command's parser is built before JAX is imported). :func:`add_log_options` adds
the options to a parser; :func:`log_kwargs` turns them into :func:`diffship.data.load_runs` keywords.
"""

from __future__ import annotations

import argparse
from typing import Any

__all__ = ["add_log_options", "log_kwargs"]


def add_log_options(parser: argparse.ArgumentParser, *, html: bool = True) -> None:
    """Add ``--map FILE.toml|NAME`` (channel map for logs) and, with ``html``, ``--html FILE``."""
    g = parser.add_argument_group("logs and reports")
    g.add_argument("--map", default=None, metavar="MAP.toml|NAME",
                   help="channel map for logs given as runs (ROS 2 bag folder/.db3/.mcap, ArduPilot .bin/.tlog, PX4 "
                        ".ulg, .parquet): which topic and field is each channel, units, frame (ros: ENU/FLU -> NED/FRD), "
                        "clocks and the gap threshold; bundled: ros2_usv, ardusub, mavlink_tlog, px4 (needs pip install "
                        "'diffship[logs]')")
    if html:
        g.add_argument("--html", default=None, metavar="FILE",
                       help="write a self-contained HTML report (text and figures embedded) to FILE")


def log_kwargs(args: argparse.Namespace) -> dict[str, Any]:
    """``load_runs`` keywords from the parsed ``--map`` (empty when not given)."""
    return {"channel_map": args.map} if getattr(args, "map", None) else {}
