r"""Is a fitted model physically admissible outside its training runs?

A model fitted on zigzags is used to predict turning circles; terms the zigzags never excite
(e.g. :math:`N_{rrr}`, :math:`N_{vvr}`) are free to go anywhere, and a fit that reproduces its
training runs can be unstable in a hard turn. :func:`admissibility` checks, over an operating
envelope wider than the training data:

1. **Standard manoeuvres simulate** without blow-up (ships with a rudder input ``delta``):
   35° turning circle both sides, 10/10 and 20/20 zigzags, 20° pull-out. The speed must stay
   positive.
2. **Self-damping** of every velocity state :math:`\nu_i` (surge, sway, yaw for a 3-DOF ship):
   :math:`\partial\dot\nu_i/\partial\nu_i < 0` at every point of a grid over the envelope
   (rudder amidships, other inputs at their given values). A positive value means that motion
   in that DOF feeds itself: the damping term has turned destabilising. The free parameters that
   changed this derivative most (relative to the reference model, where there is one) are named.
3. **Straight-line stability**: eigenvalues of the sway–yaw linearisation on a straight course.
   Many full-form ships are course-unstable, so this is reported, and flagged only where the
   fitted model's stability differs qualitatively from the reference model's (stable ↔
   unstable) or its unstable root is more than three times the reference one.

The envelope is the box spanned by the training runs' velocities (×1.5) and by the 35° turning
circle of the fitted model and of the reference model (where one exists), so it always covers
"at least that of a 35° turn and a 20/20 zigzag".
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .compiled import compiled
from .data import Run
from .errors import ModelError
from .manoeuvres.drive import pull_out, turning_circle, zigzag
from .models import AbstractModel

__all__ = ["Check", "Admissibility", "admissibility"]


@dataclasses.dataclass(frozen=True)
class Check:
    """One admissibility check: ``passed`` with a sentence, and the parameters to blame."""

    name: str
    passed: bool
    detail: str
    offending: tuple[str, ...] = ()
    warning_only: bool = False


@dataclasses.dataclass(frozen=True, eq=False)
class Admissibility:
    """All checks of a model and the manoeuvres simulated for them."""

    model: str
    checks: tuple[Check, ...]
    envelope: dict[str, tuple[float, float]]
    runs: dict[str, Run]

    @property
    def ok(self) -> bool:
        return all(c.passed or c.warning_only for c in self.checks)

    @property
    def offending(self) -> tuple[str, ...]:
        out: list[str] = []
        for c in self.checks:
            if not c.passed:
                out.extend(n for n in c.offending if n not in out)
        return tuple(out)

    def summary(self) -> str:
        head = ("ADMISSIBLE" if self.ok else "NOT ADMISSIBLE") + f": model {self.model} outside its training runs"
        env = ", ".join(f"{k} ∈ [{lo:.3g}, {hi:.3g}]" for k, (lo, hi) in self.envelope.items())
        lines = [head, f"  envelope checked: {env}"]
        for c in self.checks:
            mark = "ok  " if c.passed else ("warn" if c.warning_only else "FAIL")
            blame = f" (parameters: {', '.join(c.offending)})" if c.offending and not c.passed else ""
            lines.append(f"  [{mark}] {c.name}: {c.detail}{blame}")
        if not self.ok:
            lines.append("  → constrain the offending parameters: a prior (--prior NAME=MEAN±SD), fix them at the "
                         "reference values (--fix), or add a manoeuvre that excites them to the training runs")
        return "\n".join(lines)

    def as_json(self) -> dict:
        return {"ok": self.ok, "model": self.model, "envelope": {k: list(v) for k, v in self.envelope.items()},
                "offending": list(self.offending),
                "checks": [dataclasses.asdict(c) for c in self.checks]}


_VEL = ("u", "v", "r", "p", "q", "w")


def _velocity_states(model: AbstractModel) -> list[str]:
    return [s for s in _VEL if s in model.state_names]


def _state_box(model: AbstractModel, runs: Sequence[Run], factor: float) -> dict[str, tuple[float, float]]:
    box: dict[str, tuple[float, float]] = {}
    for s in _velocity_states(model):
        vals = [np.asarray(r[s], dtype=np.float64) for r in runs if s in r.channels]
        if not vals:
            continue
        v = np.concatenate(vals)
        lo, hi = float(np.min(v)), float(np.max(v))
        if s == "u":
            box[s] = (lo / factor if lo > 0 else lo * factor, hi * factor if hi > 0 else hi / factor)
        else:
            m = factor * max(abs(lo), abs(hi))
            box[s] = (-m, m)
    return box


def _merge(a: dict, b: dict) -> dict:
    out = dict(a)
    for k, (lo, hi) in b.items():
        out[k] = (min(lo, out[k][0]), max(hi, out[k][1])) if k in out else (lo, hi)
    return out


class _Linearised(eqx.Module):
    """Compile-cache owner of the admissibility checks' derivatives of the vector field (the
    model, states and inputs are arguments, so a new fit reuses the programs, and a new process
    loads them: :mod:`diffship.compiled`)."""

    vel: tuple[int, ...] = eqx.field(static=True)  # indices of the velocity states checked
    i: int = eqx.field(static=True, default=0)  # the state whose self-damping is blamed

    def diagonals(self, model, xs, u):
        """``∂ν̇_i/∂ν_i`` of every velocity state at every row of ``xs``."""
        def diag(xi):
            jac = jax.jacfwd(lambda y: model.vector_field(0.0, y, u))(xi)
            return jnp.stack([jac[k, k] for k in self.vel])
        return jax.vmap(diag)(xs)

    def damping_gradient(self, model, theta, x, u):
        """Gradient of ``∂ν̇_i/∂ν_i`` at ``x`` with respect to every parameter."""
        def d_of(th):
            m = model.with_params(th)
            return jax.jacfwd(lambda y: m.vector_field(0.0, y, u))(x)[self.i, self.i]
        return jax.grad(d_of)(theta)

    def jacobian(self, model, x, u):
        """State Jacobian of the vector field at ``x``."""
        return jax.jacfwd(lambda y: model.vector_field(0.0, y, u))(x)


def _call(owner, name, *args):
    fn, _ = compiled(owner, name, tuple(args))
    return np.asarray(fn(*args))


def _self_damping(model: AbstractModel, box: dict[str, tuple[float, float]], u_const: np.ndarray,
                  n_grid: int) -> tuple[dict[str, float], dict[str, np.ndarray]]:
    """Largest ∂ν̇_i/∂ν_i over the grid, and the state where it occurs."""
    states = list(model.state_names)
    vel = [s for s in _velocity_states(model) if s in box]
    axes = [np.linspace(*box[s], n_grid) for s in vel]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, len(vel))
    x = np.zeros((grid.shape[0], len(states)))
    for j, s in enumerate(vel):
        x[:, states.index(s)] = grid[:, j]
    owner = _Linearised(vel=tuple(states.index(s) for s in vel))
    d = _call(owner, "diagonals", model, jnp.asarray(x), jnp.asarray(u_const, dtype=jnp.float64))
    worst = {s: float(np.nanmax(d[:, j])) for j, s in enumerate(vel)}
    where = {s: x[int(np.nanargmax(d[:, j]))] for j, s in enumerate(vel)}
    return worst, where


def _blame(model: AbstractModel, reference: AbstractModel | None, state: str, x: np.ndarray, u_const: np.ndarray,
           free: Sequence[str]) -> tuple[str, ...]:
    """Free parameters whose change (from the reference, or from zero) raised ∂ν̇/∂ν most at ``x``."""
    names = model.param_names
    theta = model.theta()
    owner = _Linearised(vel=(), i=model.state_names.index(state))
    g = _call(owner, "damping_gradient", model, jnp.asarray(theta, dtype=jnp.float64),
              jnp.asarray(x, dtype=jnp.float64), jnp.asarray(u_const, dtype=jnp.float64))
    base = np.asarray(reference.theta()) if reference is not None else np.zeros_like(g)
    contrib = g * (np.asarray(theta) - base)
    idx = [k for k in np.argsort(-contrib) if names[k] in free and contrib[k] > 0]
    return tuple(names[k] for k in idx[:3])


def _lateral_roots(model: AbstractModel, u0: float, u_const: np.ndarray) -> np.ndarray | None:
    states = list(model.state_names)
    if not all(s in states for s in ("u", "v", "r")):
        return None
    x = np.zeros(len(states))
    x[states.index("u")] = u0
    jac = _call(_Linearised(vel=()), "jacobian", model, jnp.asarray(x), jnp.asarray(u_const, dtype=jnp.float64))
    k = [states.index("v"), states.index("r")]
    return np.linalg.eigvals(jac[np.ix_(k, k)])


def admissibility(
    model: AbstractModel,
    *,
    initial: Mapping[str, float],
    inputs: Mapping[str, float] | None = None,
    training: Sequence[Run] = (),
    reference: AbstractModel | None = None,
    free: Sequence[str] | None = None,
    helm_rate_deg_s: float = 2.32,
    turn_s: float = 150.0,
    zigzag_s: float = 120.0,
    factor: float = 1.5,
    n_grid: int = 9,
) -> Admissibility:
    """Check ``model`` (see the module docstring).

    Args:
        model: the fitted model.
        initial: approach state, e.g. ``{"u": 1.179}``.
        inputs: constant values of the inputs other than the rudder (e.g. ``{"n": 10.23}``);
            for models without a rudder input, the inputs held during the damping check.
        training: the training runs (their velocities ×``factor`` join the envelope).
        reference: the reference model (e.g. the published coefficients), for blame and for the
            stability comparison.
        free: the fitted parameters (blame names only these; default all).
        helm_rate_deg_s: steering-gear rate of the manoeuvres [°/s] (use the model's scale).
        turn_s, zigzag_s: simulated durations [s] (model time).
    """
    inputs = dict(inputs or {})
    free = tuple(free) if free is not None else model.param_names
    checks: list[Check] = []
    runs: dict[str, Run] = {}
    box = _state_box(model, training, factor)
    ship = "delta" in model.input_names and "psi" in model.state_names
    u_const = np.array([float(inputs.get(n, 0.0)) for n in model.input_names])
    if ship:
        kw = dict(inputs=inputs, rudder_rate_deg_s=helm_rate_deg_s)
        plan = [("turning 35° starboard", lambda m: turning_circle(m, initial, first="starboard", duration=turn_s, **kw)),
                ("turning 35° port", lambda m: turning_circle(m, initial, first="port", duration=turn_s, **kw)),
                ("zigzag 10/10", lambda m: zigzag(m, initial, rudder_deg=10.0, duration=zigzag_s, **kw)),
                ("zigzag 20/20", lambda m: zigzag(m, initial, rudder_deg=20.0, duration=zigzag_s, **kw)),
                ("pull-out 20°", lambda m: pull_out(m, initial, turn_s=turn_s / 2, settle_s=turn_s / 2, **kw))]
        for name, sim in plan:
            try:
                run = sim(model)
            except ModelError as exc:
                checks.append(Check(f"{name} simulates", False, str(exc)))
                continue
            runs[name] = run
            umin = float(np.min(run["u"])) if "u" in run.channels else math.nan
            ok = not (umin <= 0)
            checks.append(Check(f"{name} simulates", ok, "no blow-up" + (f"; lowest speed {umin:.3g} m/s" if ok
                                else f", but the speed falls to {umin:.3g} m/s")))
        sims = list(runs.values())
        if reference is not None:
            try:
                sims.append(turning_circle(reference, initial, duration=turn_s, **kw))
            except ModelError:
                pass
        box = _merge(box, _state_box(model, sims, 1.0))
    if "u" in box and "u" in initial:
        box["u"] = (min(box["u"][0], 0.5 * initial["u"]), max(box["u"][1], initial["u"]))
    if box:
        worst, where = _self_damping(model, box, u_const, n_grid)
        for s, d in worst.items():
            ok = d < 0
            blame = () if ok else _blame(model, reference, s, where[s], u_const, free)
            at = ", ".join(f"{n}={where[s][model.state_names.index(n)]:.3g}" for n in box)
            checks.append(Check(f"{s}-motion self-damping ∂{s}̇/∂{s} < 0", ok,
                                f"largest {d:.3g} 1/s" + ("" if ok else f" at {at}"), blame))
    blamed = tuple(dict.fromkeys(n for c in checks if not c.passed for n in c.offending))
    checks = [dataclasses.replace(c, offending=blamed) if c.name.endswith("simulates") and not c.passed else c
              for c in checks]
    if ship and "u" in initial:
        roots = _lateral_roots(model, float(initial["u"]), u_const)
        if roots is not None:
            lam = float(np.max(roots.real))
            detail = f"sway–yaw roots {', '.join(f'{z.real:.3g}' for z in roots)} 1/s"
            ok, warn = True, True
            if reference is not None:
                ref = _lateral_roots(reference, float(initial["u"]), u_const)
                lam_ref = float(np.max(ref.real))
                detail += f" (reference: {', '.join(f'{z.real:.3g}' for z in ref)})"
                if (lam > 0) != (lam_ref > 0) or (lam > 0 and lam > 3 * lam_ref):
                    ok = False
                    detail += "; straight-line stability differs from the reference"
            checks.append(Check("straight-line stability", ok, detail, warning_only=warn))
    return Admissibility(model.name, tuple(checks), box, runs)
