r"""The augmented model: a base model with any number of effects, itself a model.

:class:`Augmented` wraps a base model and effects into a new
:class:`~diffship.models.AbstractModel`, so :func:`~diffship.fit.fit_output_error`,
:func:`~diffship.simulate.simulate` and :func:`~diffship.metrics.evaluate` work on it
unchanged. Its parameters are the base parameters followed by the effect parameters; extra
states (actuator and delay states) follow the base states; extra inputs (measured wind) follow
the base inputs. At the null values the vector field and outputs equal the base ones.

Hooks, applied in this order inside :meth:`Augmented.vector_field`:

* ``input``: transforms the steering inputs before the base model sees them
  (input delay → rate limit → actuator lag, then model-specific input terms);
* ``force``: the summed added force :math:`\Delta\tau = (\Delta X, \Delta Y, \Delta N)` on a 3-DOF
  model, turned into accelerations with the base model's own mass matrix
  (``base.solve_mass``), i.e. :math:`\dot\nu = \dot\nu_{base} + M^{-1}\Delta\tau`;
* ``kinematics``: ocean current and heading-sensor bias. The velocity states are over ground
  (what GNSS measures), the hydrodynamics see :math:`\nu_r = \nu_g - R^\top(\psi_t) v_c`, and
  positions follow :math:`\dot\eta_{1:2} = R(\psi_t)\,\nu_g` with the true heading
  :math:`\psi_t = \psi - b_\psi`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ...errors import ModelError
from .._base import AbstractModel
from ...params import Param, ParamSpec
from ._base import Effect, body_velocity, is_ship3, parts
from .current import Current, CurrentTrend
from .sensor import HeadingBias

__all__ = ["Augmented"]

_HOOK_ORDER = {"input": 0, "force": 1, "kinematics": 2}


class Augmented(AbstractModel):
    """``base`` with ``effects`` added; itself a model (parameters: base's, then effects')."""

    base: AbstractModel
    effects: tuple[Effect, ...]

    def __init__(self, base: AbstractModel, effects: Sequence[Effect] = ()):
        if isinstance(base, Augmented):  # flatten nesting
            effects = tuple(base.effects) + tuple(effects)
            base = base.base
        effects = tuple(sorted(effects, key=lambda e: (_HOOK_ORDER.get(e.hook, 9), e.input_order)))
        names = [e.name for e in effects]
        if len(set(names)) != len(names):
            raise ModelError(f"effect added twice: {names}")
        pn = list(base.param_names) + [n for e in effects for n in e.param_names]
        if len(set(pn)) != len(pn):
            raise ModelError(f"parameter name clash between {base.name} and effects {names}")
        self.base = base
        self.effects = effects

    # -- structure (instance-level, unlike plain models) ---------------------------------
    @property
    def name(self) -> str:  # type: ignore[override]
        return self.base.name + "".join("+" + e.name for e in self.effects)

    @property
    def state_names(self) -> tuple[str, ...]:  # type: ignore[override]
        return tuple(self.base.state_names) + tuple(s for e in self.effects for s in e.extra_states(self.base))

    @property
    def output_names(self) -> tuple[str, ...]:  # type: ignore[override]
        return self.base.output_names

    @property
    def angle_outputs(self) -> tuple[str, ...]:  # type: ignore[override]
        return self.base.angle_outputs

    @property
    def STATE_CHANNEL(self):  # noqa: N802 - mirrors the base-model class variable
        return getattr(self.base, "STATE_CHANNEL", {})

    @property
    def PARAMS(self) -> tuple[Param, ...]:  # type: ignore[override]  # noqa: N802
        return tuple(self.base.PARAMS) + tuple(p for e in self.effects for p in e.PARAMS)

    @property
    def input_names(self) -> tuple[str, ...]:
        extra = []
        for e in self.effects:
            extra += [n for n in e.extra_inputs if n not in extra]
        return tuple(self.base.input_names) + tuple(extra)

    @property
    def param_names(self) -> tuple[str, ...]:
        return tuple(self.base.param_names) + tuple(n for e in self.effects for n in e.param_names)

    def _owner(self, n):
        for e in self.effects:
            if n in e.param_names:
                return e
        return self.base

    def param_values(self) -> dict[str, float]:
        return {n: float(getattr(self._owner(n), n)) for n in self.param_names}

    def theta(self):
        return jnp.stack([getattr(self._owner(n), n) for n in self.param_names])

    def spec(self, base_spec: ParamSpec | None = None) -> ParamSpec:
        """Spec: ``base_spec`` (default the base model's) + effect parameters (free) at their values."""
        bs = base_spec or self.base.spec()
        vals = self.param_values()
        eff = tuple(dataclasses.replace(p, value=vals[p.name]) for e in self.effects for p in e.PARAMS)
        return ParamSpec(tuple(bs.params) + eff)

    def with_params(self, theta) -> Augmented:
        names = self.param_names
        if isinstance(theta, Mapping):
            unknown = set(theta) - set(names)
            if unknown:
                raise ModelError(f"model {self.name}: unknown parameter(s) {', '.join(sorted(unknown))}")
            d = dict(theta)
        else:
            d = {n: theta[i] for i, n in enumerate(names)}
        base = self.base.with_params({n: d[n] for n in self.base.param_names if n in d})
        effects = []
        for e in self.effects:
            sub = {n: d[n] for n in e.param_names if n in d}
            if sub:
                e = eqx.tree_at(lambda m: tuple(getattr(m, n) for n in sub), e,
                                tuple(jnp.asarray(v, dtype=jnp.float64) for v in sub.values()))
            effects.append(e)
        return eqx.tree_at(lambda m: (m.base, m.effects), self, (base, tuple(effects)))

    def canonical(self, values):
        """The base model's canonical relabelling (e.g. Nomoto T1 ↔ T2), effect values unchanged."""
        if hasattr(self.base, "canonical"):
            b = {n: values[n] for n in self.base.param_names}
            return {**values, **self.base.canonical(b)}
        return dict(values)

    # -- dynamics --------------------------------------------------------------------------
    def _split_x(self, x):
        nb = len(self.base.state_names)
        parts, off = [], nb
        for e in self.effects:
            k = len(e.extra_states(self.base))
            parts.append(x[off:off + k])
            off += k
        return x[:nb], parts

    def _split_u(self, u):
        nb = len(self.base.input_names)
        names = self.input_names
        ub = u[:nb]
        uext = {e.name: jnp.stack([u[names.index(n)] for n in e.extra_inputs]) if e.extra_inputs else None
                for e in self.effects}
        return ub, uext

    def _kin(self):
        """The current-like effects (constant or changing, :mod:`.current`; their currents add)
        and the heading bias."""
        cur = [e for e in self.effects if isinstance(e, (Current, CurrentTrend))]
        hb = [e for e in self.effects if isinstance(e, HeadingBias)]
        return cur, (hb[0] if hb else None)

    def vector_field(self, t, x, u):
        r"""With a current the velocity states are **over ground** (what GNSS measures, so the
        initial state does not depend on the current): the hydrodynamics see
        :math:`\nu_r = \nu_g - R^\top(\psi_t) v_c` and, for a constant current,
        :math:`\dot\nu_g = \dot\nu_r + \tfrac{d}{dt}R^\top v_c = \dot\nu_r + r\,(v_{c,y}^b, -v_{c,x}^b, 0)`;
        positions follow :math:`\dot\eta_{1:2} = R(\psi_t)\nu_g` with true heading
        :math:`\psi_t = \psi - b_\psi`. Computed on scalar components (:meth:`vector_field_parts`)
        and stacked once."""
        return jnp.stack(self.vector_field_parts(t, parts(x), parts(u)))

    def vector_field_parts(self, t, xs: tuple, us: tuple) -> tuple:
        """:meth:`vector_field` on tuples of scalar components (every hook in its parts form:
        no vector is stacked inside the time step but the result)."""
        base = self.base
        nb, nu_b = len(base.state_names), len(base.input_names)
        xb, ub = list(xs[:nb]), tuple(us[:nu_b])
        xes, off = [], nb
        for e in self.effects:
            k = len(e.extra_states(base))
            xes.append(tuple(xs[off:off + k]))
            off += k
        names = self.input_names
        uext = {e.name: jnp.stack([us[names.index(n)] for n in e.extra_inputs]) if e.extra_inputs else None
                for e in self.effects}
        cur, hb = self._kin()
        kin = (bool(cur) or hb is not None) and is_ship3(base)
        xg = tuple(xb)
        if kin:
            ip, iu = base.state_names.index("psi"), base.state_names.index("u")
            psi_t = xb[ip] - hb.b_psi if hb is not None else xb[ip]
            c, s = jnp.cos(psi_t), jnp.sin(psi_t)
            if cur:
                vels = [e.velocity(t) for e in cur]
                Vx = sum(v[0][0] for v in vels)
                Vy = sum(v[0][1] for v in vels)
                Ax = sum(v[1][0] for v in vels)
                Ay = sum(v[1][1] for v in vels)
                vcb_x, vcb_y = c * Vx + s * Vy, -s * Vx + c * Vy
                acb_x, acb_y = c * Ax + s * Ay, -s * Ax + c * Ay
                xb[iu] = xb[iu] + (-vcb_x)  # through-water velocities
                xb[iu + 1] = xb[iu + 1] + (-vcb_y)
        xb = tuple(xb)
        extra_dots: list = []
        for e, xe in zip(self.effects, xes):
            if e.hook == "input":
                ub, dxe = e.apply_input_parts(base, t, xb, xe, ub)
                extra_dots.extend(dxe)
        dx = list(base.vector_field_parts(t, xb, ub))
        forces = [e.force_parts(base, t, xb, ub, uext[e.name]) for e in self.effects if e.hook == "force"]
        if forces:
            i = base.state_names.index("u")
            dtau = list(forces[0])
            for f in forces[1:]:
                dtau = [a + b for a, b in zip(dtau, f)]
            acc = base.solve_mass_parts(*dtau)
            for k in range(3):
                dx[i + k] = dx[i + k] + acc[k]
        if kin:
            ug, vg, rg = body_velocity(base, xg)
            dx[base.state_names.index("x0")] = c * ug - s * vg
            dx[base.state_names.index("y0")] = s * ug + c * vg
            if cur:
                # d/dt (Rᵀ v_c) = Ṙᵀ v_c + Rᵀ v̇_c (the second term only for a changing current)
                dx[iu] = dx[iu] + (rg * vcb_y + acb_x)
                dx[iu + 1] = dx[iu + 1] + (-rg * vcb_x + acb_y)
        return tuple(dx) + tuple(extra_dots)

    def effect_twins(self) -> dict[str, str]:
        """The base's (:meth:`AbstractModel.effect_twins`)."""
        return self.base.effect_twins()

    def observe(self, x, u):
        xb, _ = self._split_x(x)
        ub, _ = self._split_u(u)
        return self.base.observe(xb, ub)

    def initial_state(self, y0: Mapping[str, float]) -> np.ndarray:
        xb = np.asarray(self.base.initial_state(y0), dtype=np.float64)
        extra = [v for e in self.effects for v in e.extra_init(self.base, y0)]
        return np.concatenate([xb, np.asarray(extra, dtype=np.float64)])

    def states_for_channels(self, channels) -> tuple[str, ...]:
        return self.base.states_for_channels(channels)
