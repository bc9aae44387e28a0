r"""What became of a fit, as a value: :class:`RESULTS`, extended from optimistix's.

optimistix extends lineax's ``RESULTS`` and diffrax extends optimistix's (``diffrax/_solution.py``);
diffship extends optimistix's the same way, so a solver's own outcome (``successful``,
``nonlinear_max_steps_reached``, ``singular``, ...) and diffship's (a simulation that blows up, a
Kalman filter that diverges, a Jacobian without full rank) are one enumeration. A
:class:`~diffship.fit.FitResult` carries one of these values as ``result``; its ``status`` is the
message, its ``converged`` whether the value is ``successful``, and :func:`usable` says whether the
estimate may be used at all (a fit stopped at its step limit is usable with a warning; one whose
simulation blows up is not).

Status is never free text read from a private table: compare values
(``res.result == RESULTS.simulation_blew_up``) and print ``message(res.result)``.
"""

from __future__ import annotations

import jax
import optimistix as optx

__all__ = ["RESULTS", "as_diffship", "by_name", "code", "from_code", "message", "name_of", "usable"]


class RESULTS(optx.RESULTS):  # pyright: ignore[reportGeneralTypeIssues]
    """Outcomes of a fit (optimistix's, plus diffship's own)."""

    successful = ""
    simulation_blew_up = "the simulation blows up at the final parameters"
    filter_diverged = "the Kalman filter diverges at the final parameters"
    not_identifiable = ("the data do not identify every free parameter (Jacobian rank deficient: infinite "
                        "standard errors)")
    did_not_settle = "the equation-error Gauss–Newton iteration did not settle"
    all_starts_blew_up = "the model diverges from every start"
    cost_stalled = ("not converged: stopped early, the cost stalled (it fell by less than the stall tolerance over "
                    "the last steps while the Gauss–Newton step was still long: a crawl, typical of a mis-specified model)")


_TREE = jax.tree_util.tree_structure(RESULTS.successful)

#: Usable estimates: converged, or stopped at a limit (reported, but the values are finite and simulate).
_USABLE = ("successful", "max_steps_reached", "did_not_settle", "not_identifiable", "cost_stalled")


def code(result) -> int:
    """The integer code of a ``RESULTS`` value (diffship's, optimistix's or lineax's: member names are
    shared, so a code is read by name through :func:`as_diffship`)."""
    return int(jax.tree_util.tree_leaves(result)[0])


def from_code(value: int) -> RESULTS:
    """The diffship ``RESULTS`` value of an integer code."""
    return jax.tree_util.tree_unflatten(_TREE, [value])


def _name_of_code(cls, c: int) -> str:
    for n, item in cls._name_to_item.items():
        if code(item) == c:
            return n
    return "unknown"


def as_diffship(result) -> RESULTS:
    """An optimistix (or lineax, or diffship) result as a diffship ``RESULTS`` value (same member)."""
    cls = getattr(result, "_enumeration", None)
    n = _name_of_code(cls, code(result)) if cls is not None else "unknown"
    return RESULTS._name_to_item.get(n, RESULTS.nonlinear_max_steps_reached)


def name_of(result) -> str:
    """The name of a ``RESULTS`` value for files and JSON (``"successful"``, ``"simulation_blew_up"``,
    ...; the solver's step limit is ``"max_steps_reached"``)."""
    n = _name_of_code(RESULTS, code(as_diffship(result)))
    return "max_steps_reached" if n == "nonlinear_max_steps_reached" else n


def by_name(name: str) -> RESULTS:
    """The ``RESULTS`` value of a name written by :func:`name_of` (an older fit file's ``"converged"`` is
    successful; other old free text is read as not converged)."""
    if name in ("converged", "successful"):
        return RESULTS.successful
    if name == "max_steps_reached":
        return RESULTS.nonlinear_max_steps_reached
    return RESULTS._name_to_item.get(name, RESULTS.nonlinear_max_steps_reached)


def message(result) -> str:
    """Readable text of a ``RESULTS`` value: ``"converged"`` for success."""
    r = as_diffship(result)
    if r == RESULTS.successful:
        return "converged"
    if name_of(r) == "max_steps_reached":
        return "not converged: the solver reached its step limit before meeting its tolerances"
    return RESULTS._index_to_message[code(r)] or name_of(r)


def usable(result) -> bool:
    """Whether an estimate with this outcome may be used (with its warnings)."""
    return name_of(result) in _USABLE
