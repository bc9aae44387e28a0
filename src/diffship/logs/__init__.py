"""Robot logs as runs: ROS 2 bags (sqlite3, MCAP), ArduPilot DataFlash and MAVLink logs, PX4 ULog,
parquet; channel maps (TOML), frames (REP-103 ENU/FLU → NED/FRD), clocks, one grid, gaps."""

from .channelmap import ChannelMap, ChannelSpec, SourceSpec, bundled_maps, load_map
from .frames import euler_from_quaternion
from .load import gap_report, log_runs, read_log
from .readers import LOG_SUFFIXES, is_log, require_extra

__all__ = ["LOG_SUFFIXES", "ChannelMap", "ChannelSpec", "SourceSpec", "bundled_maps", "euler_from_quaternion",
           "gap_report", "is_log", "load_map", "log_runs", "read_log", "require_extra"]
