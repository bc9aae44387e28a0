r"""Trim: the straight-course equilibrium of any manoeuvring model with a surge state ``u``.

On a straight course at zero rudder (``v = r = 0``, ``δ = 0``) the surge equation of the
model's vector field :math:`f` must balance,

.. math::
    \dot u = f_u\big(x(u),\ (\delta = 0, c)\big) = 0,

where ``c`` is the model's propulsion input (``n`` [rev/s] for MMG, ``thrust`` for the VMMs,
``tau_x`` for Fossen 3-DOF with force inputs, ``rpm`` for water jets). :func:`trim` solves it
for ``c`` at a given speed (self-propulsion point) or for ``u`` at a given ``c`` (the speed the
ship settles to). The root is bracketed on a grid (the surge force is monotone in each of them
in the useful range) and refined with optimistix's bisection; the result says whether the
residual acceleration is below ``atol``.

Starting a standard manoeuvre from a trimmed state keeps the approach steady: the published
KVLCC2 MMG set at the measured 10.23 rev/s settles at about 1.02 m/s, not the test's 1.179 m/s.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx

from .errors import ModelError
from .models import AbstractModel

__all__ = ["Trim", "propulsion_input", "trim"]


@dataclasses.dataclass(frozen=True)
class Trim:
    """A straight-course equilibrium.

    Attributes:
        speed: surge speed u [m/s].
        inputs: every input of the model (``delta`` = 0 and the propulsion input), model units.
        solved_for: ``"speed"`` or the name of the input solved for.
        residual: surge acceleration at the solution [m/s²].
        ok: ``|residual| <= atol``.
        status: readable status.
    """

    speed: float
    inputs: dict[str, float]
    solved_for: str
    residual: float
    ok: bool
    status: str

    def initial(self) -> dict[str, float]:
        """Initial state mapping for :mod:`diffship.manoeuvres` (``{"u": speed}``)."""
        return {"u": self.speed}


def propulsion_input(model: AbstractModel, name: str | None = None) -> str:
    """The input trim solves for: ``name``, or the model's only input other than ``delta``."""
    others = [n for n in model.input_names if n != "delta"]
    if name is not None:
        if name not in model.input_names:
            raise ModelError(f"model {model.name} has no input '{name}'; its inputs are {model.input_names}")
        return name
    if len(others) != 1:
        raise ModelError(f"model {model.name} has inputs {model.input_names}: say which one sets the speed "
                         f"(input=...)")
    return others[0]


def _surge_fn(model: AbstractModel, which: str, fixed_u: float, inputs: Mapping[str, float], iu: int):
    names = model.input_names
    base = jnp.asarray([float(inputs.get(n, 0.0)) for n in names], dtype=jnp.float64)
    ix = model.state_names.index("u")

    def f(y, args=None):
        y = jnp.asarray(y, dtype=jnp.float64)
        if which == "speed":
            u, inp = y, base
        else:
            u, inp = jnp.asarray(fixed_u, dtype=jnp.float64), base.at[iu].set(y)
        x = jnp.zeros(len(model.state_names), dtype=jnp.float64).at[ix].set(u)
        return model.vector_field(jnp.asarray(0.0, dtype=jnp.float64), x, inp)[ix]

    return f


def trim(model: AbstractModel, *, speed: float | None = None, inputs: Mapping[str, float] | None = None,
         input: str | None = None, bracket: tuple[float, float] | None = None, atol: float = 1e-9) -> Trim:
    """Straight-course equilibrium at zero rudder.

    Give ``speed`` [m/s] to find the propulsion input (``input``, default the model's only
    non-rudder input) that holds it, or ``inputs`` (e.g. ``{"n": 10.23}``) to find the speed.
    ``bracket``: search interval for the unknown (default: grown from (0, 1) until the surge
    acceleration changes sign).
    """
    if "u" not in model.state_names:
        raise ModelError(f"model {model.name} has no surge state 'u' (states {model.state_names}); trim needs one. "
                         "Give the approach speed directly (e.g. predict --speed)")
    if (speed is None) == (not inputs):
        raise ModelError("trim: give either speed= (to find the propulsion input) or inputs= (to find the speed)")
    inputs = dict(inputs or {})
    unknown = set(inputs) - set(model.input_names)
    if unknown:
        raise ModelError(f"trim: model {model.name} has no input(s) {', '.join(sorted(unknown))}; "
                         f"its inputs are {model.input_names}")
    inputs["delta"] = 0.0
    if speed is not None:
        which = propulsion_input(model, input)
        iu = model.input_names.index(which)
        if not speed > 0:
            raise ModelError(f"trim: speed must be positive, got {speed!r} m/s")
    else:
        missing = [n for n in model.input_names if n not in inputs]
        if missing:
            raise ModelError(f"trim: give the model's input(s) {', '.join(missing)} (inputs=...)")
        which, iu = "speed", -1
    f = _surge_fn(model, which, speed or 0.0, inputs, iu)
    fv = jax.jit(jax.vmap(f))
    lo, hi = bracket if bracket else (1e-3, 1.0)
    grid = None
    for _ in range(40):
        grid = np.linspace(lo, hi, 65)
        vals = np.asarray(fv(jnp.asarray(grid)))
        s = np.sign(vals)
        change = np.nonzero(np.isfinite(vals[:-1]) & np.isfinite(vals[1:]) & (s[:-1] * s[1:] <= 0))[0]
        if change.size:
            a, b = float(grid[change[0]]), float(grid[change[0] + 1])
            break
        if bracket:
            raise ModelError(f"trim of {model.name}: the surge acceleration does not change sign for {which} in "
                             f"[{lo:g}, {hi:g}] (values {vals[0]:.3g} to {vals[-1]:.3g}); widen bracket=")
        hi *= 2.0
    else:
        raise ModelError(f"trim of {model.name}: no equilibrium {which} found up to {hi:g}; "
                         "check the model's resistance and propulsion parameters")
    fa, fb = float(f(jnp.asarray(a))), float(f(jnp.asarray(b)))
    if fa == 0.0 or fb == 0.0:  # a grid point is the root (bisection needs a strict sign change)
        y = a if fa == 0.0 else b
    else:
        sol = optx.root_find(f, optx.Bisection(rtol=1e-12, atol=1e-12), jnp.asarray(0.5 * (a + b)),
                             options={"lower": a, "upper": b}, throw=False, max_steps=400)
        y = float(sol.value)
    res = float(f(jnp.asarray(y)))
    ok = abs(res) <= atol
    vals_in = {n: float(inputs.get(n, 0.0)) for n in model.input_names}
    if which != "speed":
        vals_in[which] = y
    u = y if which == "speed" else float(speed)
    status = (f"equilibrium: u = {u:.6g} m/s with " + ", ".join(f"{n} = {v:.6g}" for n, v in vals_in.items())
              + ("" if ok else f" (NOT converged: surge acceleration {res:.3g} m/s²)"))
    return Trim(speed=u, inputs=vals_in, solved_for=which, residual=res, ok=ok, status=status)
