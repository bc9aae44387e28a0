r"""Decided early: a candidate that closes the gap alone leaves the far weaker ones unrefitted.

:meth:`~.which.Search.refit_singles` refits the first candidate by screening rank first, beside the
no-effect reference and the base's held-out score. When that candidate passes the acceptance rule
(:meth:`~.which.Search.judge`) against the reference — which has a structural gap,
:math:`E_{ref} \ge` gate — and alone brings the held-out error under the gap gate,
:math:`E_1 <` gate, the gap is closed: the candidates whose screened share (predicted fraction
:math:`f_k`, :mod:`.screen`) is below ``decided_share`` (5 %) of its own, :math:`f_k < 0.05\,f_1`,
are not refitted. Under the gate no further effect can lower E by more than the noise band, so
the selection would not change; their rows in the ranking and the confidence line say why.
Otherwise every candidate is refitted as before. The decision depends on results only, never on
which refit finished first (the other candidates wait for it); ``refit_all`` or
``decided_share = 0`` turn it off.

Measured: on the USV current case (``benchmarks/diagnose_current_case.py``) the six candidates left out (shares 0.0004–0.0023
against the current's 0.71) were 28 of the 39 s of refits; the user's command went from 95–102 s to
70–73 s cold on 2 cores with the same result. On the independent grid (74 scenarios,
``benchmarks/results/diagnosis_independent.md``, run with and without ``refit_all``) every selection, confidence level and
validation error was the same as with every candidate refitted.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

__all__ = ["left_out", "remaining"]


def left_out(search, first: str, refit, ref, rest: Sequence[str], shares: Mapping[str, float]) -> dict[str, str]:
    """``{candidate: reason}`` for the candidates of ``rest`` not to refit because ``first`` (its
    ``refit`` = ``(RefitResult, Score)``) closed the gap alone against the reference score ``ref``;
    empty when it did not (module docstring). ``search``: the :class:`~.which.Search` (its rule, gate
    and options)."""
    o = search.options
    rf, sc = refit
    j = search.judge(rf, ref, sc, [first], base=ref)
    if not (j.ok and j.shrink >= o.min_shrink and sc.E < search.gate):
        return {}
    f1 = shares.get(first, 0.0)
    return {n: (f"not refitted: {first} alone brought the held-out E under the gap gate ({sc.E:.3g} < "
                f"{search.gate:.3g}); screened share {shares.get(n, 0.0):.2g} below "
                f"{100 * o.decided_share:.0f} % of its {f1:.2g}")
            for n in rest if shares.get(n, 0.0) < o.decided_share * f1}


def remaining(search, names: Sequence[str], head, ref, shares: Mapping[str, float]) -> list[str]:
    """The candidates of ``names[1:]`` still to refit once ``names[0]`` was (``head``: its
    ``(RefitResult, Score)`` or the exception it raised; ``ref``: the reference score, or ``None``
    when unknown). Those left out go to ``search.not_refitted`` with the reason, and
    ``search.decided`` names the candidate that closed the gap."""
    rest = list(names[1:])
    if ref is None or isinstance(head, Exception):
        return rest
    skip = left_out(search, names[0], head, ref, rest, shares)
    if skip:
        search.decided = names[0]
        search.not_refitted.update(skip)
        search.say(f"  {names[0]} closes the gap (validation E {ref.E:.3g} → {head[1].E:.3g}, under the gate "
                   f"{search.gate:.3g}): {len(skip)} candidate(s) screened under "
                   f"{100 * search.options.decided_share:.0f} % of its share not refitted ({', '.join(skip)})")
    return [n for n in rest if n not in skip]
