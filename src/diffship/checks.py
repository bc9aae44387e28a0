"""Checks of the runs against a model and the declared conventions, before any compute: the channels a
model needs, motion that changes, inputs that move, the rudder sign (the heading turns the way the rudder
says) and the yaw direction (the yaw follows the yaw moment: clockwise heading, NED/FRD). Each stops with
one line naming the run and the fix. Shared by the command lines (``fit``, ``diagnose``, ``predict --measured``).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .data import Run
from .errors import DataError, DiffshipError
from .manoeuvres import check_turn_direction

__all__ = ["check_channels", "check_excitation", "check_motion", "check_rudder_sign", "check_runs",
           "check_yaw_direction"]

#: Channels the fits leave out by default (as :data:`diffship.fit.problem.NOT_FITTED_BY_DEFAULT`).
_POSITIONS = ("x0", "y0")


def _constant(a) -> bool:
    """One value in every sample (to 1e-9 of its size; zero everywhere included)."""
    a = np.asarray(a, dtype=np.float64)
    return float(np.ptp(a)) <= 1e-9 * max(float(np.max(np.abs(a))), 1e-300)


def _loc(run) -> str:
    return f"{run.metadata.get('source', run.name)} (run '{run.name}')"


def check_runs(model, train, val=(), channels=None) -> None:
    """The checks of runs against a model before any compute, in this order: the channels it needs
    (:func:`check_channels`) and motion that changes (:func:`check_motion`) in every run, inputs that move
    in the training runs (:func:`check_excitation`)."""
    runs = list(train) + list(val)
    check_channels(model, runs, channels)
    check_motion(model, runs, channels)
    check_excitation(model, list(train))


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
            problems.append(f"{_loc(run)} lacks {', '.join(missing)} (its columns: "
                            f"{', '.join(('time', *run.channel_names))})")
    if problems:
        inputs = [c for c in runs[0].channel_names if c in ("delta", "n", "rpm", "tau_x")]
        raise DiffshipError(
            f"model {model.name} needs channels {', '.join(dict.fromkeys(need))}: " + "; ".join(problems)
            + ". Map file columns with --columns NAME=COLUMN, or choose a model these runs can drive"
            + (f" (inputs here: {', '.join(inputs)})" if inputs else " (these runs have no input channel)"))


def check_excitation(model, train) -> None:
    """Stop when no input the model needs moves in the training runs.

    The rule: every input of ``model.input_names`` that a run must have (those without an
    ``INPUT_DEFAULTS`` value) holds one value, the same, over every sample of every training run (runs held
    still at different values are not refused: their steady states differ). The input's terms
    are identified by the motion's answer to the input's changes (with a rudder that never moves, a rudder
    gain and a rudder offset cannot be told apart); without this check the fit searches for minutes and
    finds no usable fit. A model with no such input (a free decay) is not checked; validation runs may
    hold their inputs still.
    """
    optional = getattr(model, "INPUT_DEFAULTS", {}) or {}
    need = [n for n in model.input_names if n not in optional and all(r.has(n) for r in train)]
    if not train or not need:
        return
    values = {n: np.concatenate([np.asarray(r[n], dtype=np.float64) for r in train]) for n in need}
    if not all(_constant(a) for a in values.values()):
        return
    held = ", ".join(f"{n} is 0" if not np.any(values[n]) else f"{n} holds one value" for n in need)
    raise DataError(
        f"model {model.name}: the training runs carry no excitation for {', '.join(need)}: {held} in every sample "
        f"of {', '.join(_loc(r) for r in train)}; the fit needs runs where the input moves (a zigzag, a turn, a "
        f"step). If the file holds the input under another column, map it: --columns {need[0]}=COLUMN")


def check_motion(model, runs, channels=None) -> None:
    """Stop at a run in which every channel the fit compares holds one value (a heading and a yaw rate
    that never change: a sensor that did not record): such a run carries no information, and its fit
    percentage (1 − error/variance) is undefined. The channels: ``channels`` (``--channels``), or the
    model's outputs the run has, positions aside (as the fits' default)."""
    wanted = list(channels) if channels else [c for c in model.output_names if c not in _POSITIONS]
    bad = []
    for run in runs:
        chans = [c for c in wanted if run.has(c)]
        if chans and all(_constant(run[c]) for c in chans):
            bad.append(f"{_loc(run)}: {', '.join(f'{c} = {run[c][0] + 0.0:.4g}' for c in chans)} in every sample")
    if bad:
        raise DataError("the measured motion does not change: " + "; ".join(bad) + f". A run whose channels "
                        f"({', '.join(wanted)}) never change carries no information for model {model.name}; check the "
                        "file (a sensor that did not record, a column read under another name) or leave the run out")


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
