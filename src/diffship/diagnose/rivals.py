r"""Rivals that the runs cannot rank: effects told apart only by a manoeuvre the runs do not contain.

A force fixed to the hull (``constant_force``) turns with the ship; a current's drift stays fixed in NED. On
runs that never turn far from their initial heading — zigzags about one course, as in a basin — the two act
in nearly the same direction all the time: a body-fixed force :math:`(Y_0, N_0)` balanced by the hull's sway
damping moves the ship sideways through the water as a current moves it over the ground, and held-out runs of
the same kind cannot rank them. Measured: a 0.05-m/s drift injected into the HSVA KVLCC2 zigzags (which turn at
most 26°) was explained 41 % by a constant force and 35 % by a current on the MMG model, and a joint refit kept
both. Below the ranking (``python -m benchmarks drift_truth``): with the current held at its true value the
model predicts the held-out zigzags best of all (heading 3.1° against 4.5° with the constant force), yet on the
training runs the constant force fits better by 0.23 in −log L per sample, and the current's along-track
component is nearly free — runs that all start on one heading confound it with the speed through the water, which
the surge coefficients take (its likelihood moves by 0.0006 per sample between its estimate and the truth). The
estimate, not the ranking, loses the current, and only another heading separates them.

:func:`collinear_rivals` names such a pair a rival of the validation winner whatever their validation gains, so
that the verdict says *tie* and names the separating manoeuvre instead of a confident winner
(:meth:`diffship.diagnose.which.Search._confidence`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np

__all__ = ["HEADING_SEPARATED", "SEPARATING_TURN", "heading_turn", "collinear_rivals", "collinear_note"]

#: Effect pairs that only a large change of heading tells apart.
HEADING_SEPARATED = (frozenset({"current", "constant_force"}),)
#: The heading change [rad] beyond which a current and a force fixed to the hull act in directions 90° apart.
SEPARATING_TURN = math.pi / 2


def heading_turn(batch) -> float:
    """The largest change of the measured heading from its initial value over the runs of ``batch``
    (:class:`~diffship.fit.problem.Batch`) [rad]; ``inf`` where the heading is not among its channels."""
    if "psi" not in batch.channels:
        return math.inf
    j = list(batch.channels).index("psi")
    turn = 0.0
    for k in range(batch.ys.shape[0]):
        psi = np.asarray(batch.ys[k, :, j])[np.asarray(batch.mask[k], dtype=bool)]
        if psi.size:
            turn = max(turn, float(np.max(np.abs(np.unwrap(psi) - psi[0]))))
    return turn


def collinear_rivals(winner: str, others: Sequence[str], turn: float,
                     say: Callable[[str], None] | None = None) -> list[str]:
    """The effects of ``others`` that runs turning at most ``turn`` [rad] cannot separate from ``winner``
    (said through ``say``)."""
    if turn >= SEPARATING_TURN:
        return []
    out = [n for n in others if frozenset((winner, n)) in HEADING_SEPARATED]
    if out and say is not None:
        say(f"  {winner} and {', '.join(out)}: rivals whatever their validation gains ({collinear_note(turn)})")
    return out


def collinear_note(turn: float) -> str:
    return (f"the runs turn at most {math.degrees(turn):.0f}° from their initial heading, and a force fixed to the "
            "hull and a current's drift differ only through a larger turn")
