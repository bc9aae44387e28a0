r"""The :class:`Effect` base: parameters with a null value, hooks, and what a base model offers.

An effect is a small :class:`equinox.Module` holding the parameters ``φ`` of one physical
effect. **Null-value contract**: every parameter has a null value (``Param.value``) at which the
effect vanishes exactly, so a model augmented with effects at their null values simulates
exactly like the base model (the tests check 1e-12). Effects act through one hook each:

* ``input`` — :meth:`Effect.apply_input` transforms the base model's inputs (and may carry
  extra states, which follow the base states);
* ``force`` — :meth:`Effect.force` is an added generalised force
  :math:`\Delta\tau = (\Delta X, \Delta Y, \Delta N)` on a 3-DOF model;
* ``kinematics`` — handled by :class:`~.augmented.Augmented` itself (current, heading bias).

Each hook is written once, on arrays (``apply_input``, ``force``) or on tuples of scalar components
(``apply_input_parts``, ``force_parts``); the other form follows. :class:`~.augmented.Augmented`
composes the parts forms, so the all-effects model of a diagnosis evaluates as one expression per
stage: on the USV current case's workspace (Fossen 3-DOF with 13 effects) the time step's forward-mode
Jacobian went from 331 to 180 kernels per step and from about 185 to 125 ms per evaluation on a
2-core CPU (``benchmarks/diagnose_current_case.py``).

Each effect class also says when it applies (:meth:`Effect.applicability`) and how it is
configured from the training data (:meth:`Effect.for_data`, from :class:`DataFacts`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .._base import AbstractModel, _DeclaredParams, param, parts, scalar
from .._rigid3 import AbstractShip3
from ...params import Param

__all__ = ["Effect", "DataFacts", "is_ship3", "steering_inputs", "body_velocity", "param", "parts", "scalar"]


def is_ship3(model: AbstractModel) -> bool:
    """A 3-DOF surface vessel (:class:`~diffship.models.AbstractShip3`: states ``x0, y0, psi,
    u, v, r`` and ``solve_mass(rhs)`` with the model's own mass matrix)."""
    return isinstance(model, AbstractShip3)


def rudder_only_applicability(base: AbstractModel, ship3_form: str) -> str:
    """``""`` when ``base`` is a rudder-steered model that is not 3-DOF (a Nomoto model: the effect acts on its
    input ``delta``), else why not; ``ship3_form`` says what the effect is on a 3-DOF model instead."""
    if is_ship3(base):
        return f"{base.name} is a 3-DOF model ({ship3_form})"
    if "delta" not in base.input_names:
        return f"{base.name} has no rudder input 'delta'"
    return ""


def steering_inputs(model: AbstractModel) -> tuple[int, ...]:
    """Indices of the steering inputs that actuator effects act on."""
    names = model.input_names
    for group in (("delta",), ("delta_n",), ("tau_y", "tau_z")):
        if all(n in names for n in group):
            return tuple(names.index(n) for n in group)
    return tuple(range(len(names)))


def body_velocity(base: AbstractModel, xb):
    """``(u, v, r)`` from a 3-DOF base state."""
    i = base.state_names.index("u")
    return xb[i], xb[i + 1], xb[i + 2]


@dataclasses.dataclass(frozen=True)
class DataFacts:
    """What effects take from the training runs: steering input indices, their largest
    magnitudes (rate limit), the median sample interval (time-constant clamps) and the mean
    speed ``U0`` (speed dependence)."""

    idx: tuple[int, ...]
    amplitude: tuple[float, ...]
    dt: float
    U0: float

    @classmethod
    def from_runs(cls, base: AbstractModel, runs: Sequence | None) -> DataFacts:
        idx = steering_inputs(base)
        amps, dts, speeds = [], [], []
        for r in runs or ():
            dts.append(float(np.median(np.diff(np.asarray(r.time)))))
            if all(r.has(base.input_names[i]) for i in idx):
                amps.append([float(np.max(np.abs(np.asarray(r[base.input_names[i]])))) for i in idx])
            if r.has("u"):
                u = np.asarray(r["u"])
                v = np.asarray(r["v"]) if r.has("v") else 0.0 * u
                speeds.append(float(np.mean(np.hypot(u, v))))
        amp = tuple(float(max(a, 1e-9)) for a in np.max(np.asarray(amps), axis=0)) if amps else tuple(1.0 for _ in idx)
        return cls(idx=idx, amplitude=amp, dt=float(np.median(dts)) if dts else 0.1,
                   U0=float(np.mean(speeds)) if speeds else 1.0)


class Effect(eqx.Module):
    """One candidate effect: parameters with null values, a hook, and what to say about it.

    Subclasses set ``name``, ``family``, ``hook``, declare each parameter once as a
    :func:`~diffship.models.param` field whose default is its null value (``PARAMS`` is derived), ``PROBE``
    (a plausible magnitude per parameter, for the secant screen and refit starts),
    ``MIN_RELEVANT`` (smallest magnitude worth reporting), ``smooth_null`` (False where the
    effect switches off at the null, so it is not differentiable there), ``signature``,
    ``confusable_with`` and ``separating`` (the manoeuvre that tells it from those).
    """

    name: ClassVar[str] = "effect"
    family: ClassVar[str] = ""
    hook: ClassVar[str] = "force"
    #: order among input effects (delay → rate limit → lag, then the others)
    input_order: ClassVar[int] = 9
    PARAMS: ClassVar[tuple[Param, ...]] = _DeclaredParams()  # type: ignore[assignment]  # from the param() fields
    PROBE: ClassVar[dict[str, float]] = {}
    MIN_RELEVANT: ClassVar[dict[str, float]] = {}
    smooth_null: ClassVar[bool] = True
    extra_inputs: ClassVar[tuple[str, ...]] = ()
    signature: ClassVar[str] = ""
    confusable_with: ClassVar[tuple[str, ...]] = ()
    separating: ClassVar[str] = ""

    @property
    def param_names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.PARAMS)

    @classmethod
    def _select_params(cls, names: tuple[str, ...]) -> tuple[str, ...]:
        """Every :func:`~diffship.models.param` field is a parameter of the effect."""
        return names

    def null(self) -> dict[str, float]:
        return {p.name: p.value for p in self.PARAMS}

    # -- where it applies and how it is configured ----------------------------------------
    @classmethod
    def applicability(cls, base: AbstractModel, runs: Sequence | None = None) -> str:
        """Empty string if the effect applies to ``base`` (and ``runs``), else the reason."""
        return "" if is_ship3(base) else f"{base.name} has no position/velocity states (needs a 3-DOF model)"

    @classmethod
    def for_data(cls, base: AbstractModel, facts: DataFacts) -> Effect:
        """The effect at its null value, configured for ``base`` and the training data."""
        return cls()

    # -- states ----------------------------------------------------------------------------
    def extra_states(self, base: AbstractModel) -> tuple[str, ...]:
        return ()

    def extra_init(self, base: AbstractModel, y0: Mapping[str, float]) -> list[float]:
        return []

    # -- hooks (default: nothing) ------------------------------------------------------------
    # Each hook has two forms: on arrays (``apply_input``, ``force``) and on tuples of scalar
    # components (``apply_input_parts``, ``force_parts``: what :class:`~.augmented.Augmented` calls
    # inside the integrator). An effect defines one form; the other follows from it. The parts form
    # keeps the time step free of stacked intermediate vectors: XLA on a CPU makes every stacked
    # vector with several users a kernel of its own, in every stage of every step (the USV current case's
    # all-effects workspace: ~100 such kernels per step with arrays).
    def apply_input(self, base, t, xb, xe, ub):
        """``(u_new, xe_dot)``: transformed base inputs and extra-state derivatives."""
        if type(self).apply_input_parts is not Effect.apply_input_parts:
            u_new, dxe = self.apply_input_parts(base, t, parts(xb), parts(xe), parts(ub))
            return jnp.stack(u_new), (jnp.stack(dxe) if dxe else jnp.zeros((0,), dtype=xb.dtype))
        return ub, jnp.zeros((0,), dtype=xb.dtype)

    def apply_input_parts(self, base, t, xb: tuple, xe: tuple, ub: tuple) -> tuple[tuple, tuple]:
        """:meth:`apply_input` on tuples of scalar components: ``(u_new, xe_dot)`` as tuples."""
        if type(self).apply_input is Effect.apply_input:
            return ub, ()
        u_new, dxe = self.apply_input(base, t, jnp.stack(xb), jnp.stack(xe) if xe else jnp.zeros((0,)), jnp.stack(ub))
        return parts(u_new), parts(dxe)

    def force(self, base, t, xb, ub, uext):
        """Added generalised force (ΔX, ΔY, ΔN) [N, N, N·m]."""
        if type(self).force_parts is not Effect.force_parts:
            return jnp.stack(self.force_parts(base, t, parts(xb), parts(ub), uext))
        return jnp.zeros((3,), dtype=xb.dtype)

    def force_parts(self, base, t, xb: tuple, ub: tuple, uext) -> tuple:
        """:meth:`force` on tuples of scalar components: ``(ΔX, ΔY, ΔN)``."""
        f = self.force(base, t, jnp.stack(xb), jnp.stack(ub), uext)
        return f[0], f[1], f[2]
