"""Checks of the runs against a model and the declared conventions, before any compute: the channels a
model needs, the rudder sign (the heading turns the way the rudder says) and the yaw direction (the yaw
follows the yaw moment: clockwise heading, NED/FRD). Each stops with one line naming the run and the fix.
Shared by the command lines (``fit``, ``diagnose``, ``predict --measured``).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .data import Run
from .errors import DataError, DiffshipError
from .manoeuvres import check_turn_direction

__all__ = ["check_channels", "check_rudder_sign", "check_yaw_direction"]


def check_channels(model, runs, channels=None) -> None:
    """Name every channel a model needs that a run lacks, before anything is compiled.

    Needed: every model input (``model.input_names``), the surge speed ``u`` where it is a
    state (a manoeuvring model cannot start without its speed), and the ``--channels`` asked for.
    """
    optional = getattr(model, "INPUT_DEFAULTS", {}) or {}  # inputs a run may omit (e.g. free decay: zero force)
    need = ([n for n in model.input_names if n not in optional] + (["u"] if "u" in model.state_names else [])
            + list(channels or ()))
    problems = []
    for run in runs:
        missing = [c for c in dict.fromkeys(need) if not run.has(c)]
        if missing:
            problems.append(f"{run.metadata.get('source', run.name)} (run '{run.name}') lacks {', '.join(missing)}")
    if problems:
        raise DiffshipError(
            f"model {model.name} needs channels {', '.join(dict.fromkeys(need))}: " + "; ".join(problems)
            + f". Map file columns with --columns NAME=COLUMN, or choose a model these runs can drive "
            f"(inputs here: {', '.join(c for c in runs[0].channel_names if c in ('delta', 'n', 'rpm', 'tau_x'))})")


def check_rudder_sign(runs, declared: str) -> None:
    """Stop when a run's heading clearly turns against its rudder (``--rudder-sign`` likely wrong)."""
    bad = []
    for run in runs:
        if not run.has("delta", "psi"):
            continue
        verdict = check_turn_direction(run)
        if verdict is not None and not verdict["agrees"]:
            bad.append(f"run '{run.name}' ({run.metadata.get('source', '')}): {verdict['text']}")
    if bad:
        other = "port" if declared == "starboard" else "starboard"
        raise DiffshipError(
            "the heading turns against the rudder: " + "; ".join(bad) + f". The files were read with "
            f"--rudder-sign {declared}; if positive delta turns these ships the other way, pass --rudder-sign {other}; "
            "if the heading is counter-clockwise (ROS ENU/FLU: psi, r, v, y0 negated), convert it to clockwise from "
            "north (NED) before loading (or --skip-sign-check if the record really does this, e.g. an autopilot "
            "steering against waves: its first order need not turn the ship)")


def check_yaw_direction(runs: Sequence[Run], rudder_sign: str = "starboard") -> None:
    r"""Stop when a run's yaw turns against its yaw moment (diffship: heading clockwise from north, NED/FRD,
    positive yaw moment :math:`\tau_z` turns to starboard).

    For every run with a yaw moment ``tau_z`` and a yaw rate ``r`` (or heading ``psi``): the
    correlation of :math:`\tau_z` with the yaw rate must not be clearly negative (:math:`\rho < -0.3`
    with the moment varying); counter-clockwise yaw (the ROS/ENU habit: ψ, r, v, y0 negated) shows as
    exactly that. The rudder models' check is :func:`diffship.manoeuvres.check_turn_direction`
    (the CLI runs both)."""
    bad = []
    for run in runs:
        if not run.has("tau_z") or not (run.has("r") or run.has("psi")):
            continue
        n = np.asarray(run["tau_z"])
        r = np.asarray(run["r"]) if run.has("r") else np.gradient(np.unwrap(np.asarray(run["psi"])), run.time)
        if np.std(n) <= 1e-9 * max(float(np.max(np.abs(n))), 1e-300) or np.std(r) == 0:
            continue
        rho = float(np.corrcoef(n, r)[0, 1])
        if rho < -0.3:
            bad.append(f"run '{run.name}' ({run.metadata.get('source', '')}): the yaw rate follows the negative of "
                       f"the yaw moment tau_z (correlation {rho:.2f})")
    if bad:
        raise DataError("the yaw turns against the yaw moment: " + "; ".join(bad) + ". diffship's heading is "
                        "clockwise from north (NED, FRD: positive tau_z and r turn to starboard); counter-clockwise "
                        "data (ROS ENU/FLU) need psi, r, v, y0 negated (and x0/y0 swapped from ENU) before loading, "
                        "or tau_z negated if only its sign is off (or --skip-sign-check if the record really does this)")
