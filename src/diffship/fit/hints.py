r"""What to try when no fit is usable: the options that the model and the data point to, one line each.

A fit report can name two causes without a refit:

* **Coefficients held at reference values.** On a model whose reference set applies (its reference vessel:
  :func:`~diffship.fit.priors.default_priors`), the coefficients outside the default free set are held at the
  reference values, as if they were known exactly. ``--free-hydrodynamic`` estimates them under the same
  reference priors as the free ones: the priors hold what the data do not determine.
* **A training run followed only up to a time.** When the model stops following a training run from
  :math:`t = T` (:class:`~diffship.usability.RunProblem`), the rest of that run shows what the model lacks.
  ``--horizon S`` (:math:`S` = the earliest such :math:`T`, rounded down to 10 s) fits the part it follows,
  and ``python -m diffship.diagnose`` looks for what is missing in the rest.

Measured on the HSVA KVLCC2 zigzags (MMG on ``kvlcc2_model``, the README's four training and two held-out
runs, ``--as-given``): the plain command's fit is FAILED (a held-out second overshoot 4.8° short) and names the
held coefficients; with ``--free-hydrodynamic`` it is FAILED again (2.0° short), and the training run ``Z_35_05``
is not followed from t = 66 s; with ``--free-hydrodynamic --horizon 60`` it is usable.

**Taken by the command.** ``python -m diffship.fit`` takes these steps itself (:func:`next_step`): a fit that is
not usable is refitted with the first option its report names that it has not taken yet, at most
:data:`MAX_STEPS` times, each step said in one line and listed in the report and the JSON (``steps_taken``);
``--as-given`` fits with the options as given. A usable fit is never refitted, so the answer changes only where
the options given led to no usable fit. The plain KVLCC2 command above takes both steps (87 s on 2 cores) and
is usable: held-out first overshoots 9.78° and 11.67° against 9.67° and 11.95° measured, and the 35° turn's
tactical diameters 3.04 and 3.07 L (free-running turning tests: 3.33 L starboard, 3.07 L port;
not HSVA's, whose report lists zigzags only).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

from ..models import AbstractModel
from ..params import ParamSpec
from .priors import default_priors, reference_priors

__all__ = ["MAX_STEPS", "NextStep", "held_reference_coefficients", "next_step", "next_steps"]

#: Refits the command makes after a fit that is not usable (one per option: free set, then horizon).
MAX_STEPS = 2


@dataclasses.dataclass(frozen=True)
class NextStep:
    """An option worth a try after a fit that is not usable: ``option`` (``"--free-hydrodynamic"`` or
    ``"--horizon"``), its ``value`` (the horizon [s]; ``None`` for a flag) and ``why``."""

    option: str
    value: float | None
    why: str

    def __str__(self) -> str:
        return f"{self.option}{'' if self.value is None else f' {self.value:g}'}: {self.why}"


def held_reference_coefficients(model: AbstractModel, spec: ParamSpec) -> list[str]:
    """The fixed coefficients of ``spec`` that are not vessel particulars and have a reference value a prior
    would be centred on (nonzero, in the model's reference set); empty where the reference set does not apply
    to this vessel."""
    if not len(default_priors(model, spec, 0.5)[0]):
        return []
    held = [n for n in spec.fixed_names if n not in model.PARTICULARS]
    # the same rule that puts priors on free parameters (a zero reference value is no prior)
    return [n for n in held if n in reference_priors(model, spec.free(held)).by_name]


def next_steps(model: AbstractModel, spec: ParamSpec, runs: Sequence, *, horizon: float | None,
               priors: bool, free_hydrodynamic: bool) -> list[NextStep]:
    """The options worth a try after a fit that is not usable, the free set first (module docstring;
    ``str(step)`` is its report line).

    ``runs``: the verdict's run problems (:class:`~diffship.usability.RunProblem`); ``horizon``: the
    ``--horizon`` given (or None); ``priors``: whether the reference priors are on (not ``--no-prior``);
    ``free_hydrodynamic``: whether ``--free-hydrodynamic`` was given."""
    out = []
    held = held_reference_coefficients(model, spec) if priors and not free_hydrodynamic else []
    if held:
        shown = ", ".join(held[:6]) + (f", … ({len(held)} in all)" if len(held) > 6 else "")
        out.append(NextStep("--free-hydrodynamic", None,
                            f"{len(held)} coefficient(s) are held at the reference set's values as if known exactly "
                            f"({shown}); it estimates them under their reference priors"))
    late = [p for p in runs if p.kind == "training" and math.isfinite(p.from_s) and p.from_s >= 10.0]
    if late:
        first = min(late, key=lambda p: p.from_s)
        s = 10.0 * math.floor(first.from_s / 10.0)
        if horizon is None or s < horizon:
            out.append(NextStep("--horizon", s,
                                f"the model does not follow training run {first.run} ({first.channel}) from "
                                f"t = {first.from_s:.0f} s; this fits the part it follows (python -m diffship.diagnose "
                                "looks for what the model lacks in the rest)"))
    return out


def next_step(steps: Sequence[NextStep], taken: Sequence[NextStep], given: Sequence[str] = ()) -> NextStep | None:
    """The step the command takes after a fit that is not usable: the first of ``steps`` whose option it has
    not taken yet (``taken``) and the user did not give (``given``: an option given is an override, named but
    not changed), while fewer than :data:`MAX_STEPS` were taken; ``None``: report as it is."""
    if len(taken) >= MAX_STEPS:
        return None
    done = {t.option for t in taken} | set(given)
    return next((s for s in steps if s.option not in done), None)
