r"""Candidate starts of a fit: named ones and spread ones.

A fit should not be decided by where it starts. The driver (:func:`diffship.fit.fit`) tries, together:

* the model's values (with the user's ``--init`` values where given),
* the starts a caller names (e.g. the equation-error estimate),
* the model's reference values, where they differ from the above,
* **spread starts**: each free parameter of the best named start multiplied by a log-uniform factor
  in ×0.5…×2 (sign kept; a parameter at zero moves by a normal draw of its scale), kept 10⁻³
  scales inside its bounds, from a fixed seed (the same data give the same starts, the same answer).

The count is ``n_starts`` (``--starts N``); the named ones come first.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

from ..errors import ModelError
from ..params import ParamSpec

__all__ = ["checked_start", "named_starts", "spread_starts", "SPREAD"]

#: Spread starts multiply every free parameter by a factor log-uniform in [1/SPREAD, SPREAD].
SPREAD = 2.0


def checked_start(spec: ParamSpec, values: Mapping[str, float], label: str) -> dict[str, float]:
    """A caller's start as floats, or :class:`ModelError` naming the parameter: each name a free parameter
    of the spec (a fixed one is held at the spec's value, which a start must not change unasked), each
    value one finite number. A finite value on or beyond a bound is kept: the fit moves it just inside
    (:meth:`ParamSpec.nudged`)."""
    if not isinstance(values, Mapping):
        raise ModelError(f"{label}: expected a mapping {{parameter: value}}, got {type(values).__name__}")
    out = {}
    for name, v in values.items():
        if name not in spec:
            raise ModelError(f"{label}: unknown parameter {name!r}; this model has: {', '.join(spec.names)}")
        if not spec[name].free:
            raise ModelError(f"{label}: parameter {name} is fixed (at {spec[name].value:g}), so a fit does not "
                             f"start it; free it, or leave it out of the start (spec.fix({{{name!r}: value}}) "
                             "holds it at another value)")
        try:
            f = float(v)
        except (TypeError, ValueError):
            raise ModelError(f"{label}: parameter {name}: value {v!r} is not a number") from None
        if not math.isfinite(f):
            raise ModelError(f"{label}: parameter {name}: value {f} is not finite; give a finite start value")
        out[name] = f
    return out


def named_starts(spec: ParamSpec, starts: Sequence[Mapping[str, float]] | Mapping[str, Mapping[str, float]],
                 reference: Mapping[str, float] | None = None,
                 first_label: str = "the model's values") -> list[tuple[str, dict[str, float]]]:
    """``[(label, values), ...]``: the spec's values, then ``starts``, then ``reference`` (free
    parameters only replaced; duplicates of an earlier start dropped)."""
    base = spec.values()
    named = starts.items() if isinstance(starts, Mapping) else ((f"start {i + 1}", s) for i, s in enumerate(starts))
    out = [(first_label, dict(base))]
    for label, s in named:
        out.append((label, {**base, **{k: float(v) for k, v in s.items() if k in spec.free_names}}))
    if reference:
        out.append(("the model's reference values", {**base, **{k: float(v) for k, v in reference.items()
                                                                 if k in spec.free_names}}))
    unique: list[tuple[str, dict[str, float]]] = []
    for label, vals in out:
        if not any(all(math.isclose(vals[n], u[n], rel_tol=1e-12, abs_tol=1e-15) for n in spec.free_names)
                   for _, u in unique):
            unique.append((label, vals))
    return unique


def spread_starts(spec: ParamSpec, around: Mapping[str, float], n: int, seed: int = 0) -> list[dict[str, float]]:
    """``n`` starts spread log-uniformly ×1/SPREAD…×SPREAD around ``around`` (module docstring)."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(max(n, 0)):
        vals = dict(around)
        for name in spec.free_names:
            p = spec[name]
            v = float(around[name])
            if v != 0.0:
                v *= math.exp(rng.uniform(-math.log(SPREAD), math.log(SPREAD)))
            else:
                v = float(rng.normal(0.0, p.scale))
            lo = p.lower + 1e-3 * p.scale if math.isfinite(p.lower) else -math.inf
            hi = p.upper - 1e-3 * p.scale if math.isfinite(p.upper) else math.inf
            vals[name] = float(min(max(v, lo), hi))
        out.append(vals)
    return out
