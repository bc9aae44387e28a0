"""The model interface shared by every diffship model.

A model is data plus a vector field: an :class:`equinox.Module` whose fields are its scalar
parameters (float64 JAX arrays) and static options, with

* ``vector_field(t, x, u) -> ẋ`` — a pure JAX function of one state ``x`` and one input
  vector ``u`` (inputs interpolated at time ``t`` by the simulator);
* ``observe(x, u) -> y`` — the measured channels the model predicts (``output_names``);
* ``initial_state(y0)`` — a state built from measured values at the first sample.

Models act on one trajectory; batching over runs or parameter sets is ``jax.vmap`` outside.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from ..errors import ModelError
from ..params import Param, ParamSpec

__all__ = ["AbstractModel", "scalar"]


def _as_f64(v):
    return jnp.asarray(v, dtype=jnp.float64)


def scalar(default: float | None = None):
    """A float64 scalar parameter field."""
    if default is None:
        return eqx.field(converter=_as_f64)
    return eqx.field(converter=_as_f64, default=default)


class AbstractModel(eqx.Module):
    """Base class: a vector field with named states, inputs, outputs and parameters.

    Subclasses set the class variables ``name``, ``state_names``, ``output_names`` and
    ``PARAMS`` (a tuple of :class:`~diffship.params.Param` holding default bounds, scales and
    reference values), declare one scalar field per parameter, and implement
    :meth:`vector_field`.
    """

    name: ClassVar[str] = "abstract"
    state_names: ClassVar[tuple[str, ...]] = ()
    output_names: ClassVar[tuple[str, ...]] = ()
    angle_outputs: ClassVar[tuple[str, ...]] = ("psi",)
    PARAMS: ClassVar[tuple[Param, ...]] = ()

    # -- declared structure -------------------------------------------------------------
    @property
    def input_names(self) -> tuple[str, ...]:
        raise NotImplementedError

    @property
    def param_names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.PARAMS)

    def param_values(self) -> dict[str, float]:
        return {n: float(getattr(self, n)) for n in self.param_names}

    def spec(self) -> ParamSpec:
        """Parameter spec with this model's current values (bounds, scales, free flags default)."""
        vals = self.param_values()
        return ParamSpec(tuple(dataclasses.replace(p, value=vals[p.name]) for p in self.PARAMS))

    def theta(self) -> Float[Array, " n_params"]:
        return jnp.stack([getattr(self, n) for n in self.param_names]) if self.param_names else jnp.zeros((0,))

    def with_params(self, theta: Float[Array, " n_params"] | Mapping[str, float]) -> AbstractModel:
        """A copy with new parameter values (array in ``param_names`` order, or a mapping)."""
        names = self.param_names
        if isinstance(theta, Mapping):
            unknown = set(theta) - set(names)
            if unknown:
                raise ModelError(
                    f"model {self.name}: unknown parameter(s) {', '.join(sorted(unknown))}; it has {', '.join(names)}"
                )
            new = {n: _as_f64(theta[n]) if n in theta else getattr(self, n) for n in names}
        else:
            new = {n: _as_f64(theta[i]) for i, n in enumerate(names)}
        return eqx.tree_at(lambda m: tuple(getattr(m, n) for n in names), self, tuple(new[n] for n in names))

    # -- dynamics -------------------------------------------------------------------------
    def vector_field(self, t: Float[Array, ""], x: Float[Array, " n_x"], u: Float[Array, " n_u"]) -> Float[Array, " n_x"]:
        raise NotImplementedError

    def observe(self, x: Float[Array, " n_x"], u: Float[Array, " n_u"]) -> Float[Array, " n_y"]:
        """Predicted measured channels; by default the states named in ``output_names``."""
        idx = [self.state_names.index(n) for n in self.output_names]
        return x[jnp.asarray(idx)]

    def initial_state(self, y0: Mapping[str, float]) -> np.ndarray:
        """State at the first sample from measured values (missing states start at 0)."""
        return np.array([float(y0.get(n, 0.0)) for n in self.state_names], dtype=np.float64)

    def states_for_channels(self, channels) -> tuple[str, ...]:
        """States whose initial values determine the given measured channels at t0."""
        return tuple(c for c in channels if c in self.state_names)

    # -- equation error (linear-in-parameters form) ----------------------------------------
    def derivative_channels(self) -> tuple[str, ...]:
        """Channels whose time derivatives the equation-error baseline needs."""
        return ()
