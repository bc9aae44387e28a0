r"""The model interface shared by every diffship model.

A model is data plus a vector field: an :class:`equinox.Module` whose fields are its scalar
parameters (float64 JAX arrays) and static options, with

* ``vector_field(t, x, u) -> ẋ`` — a pure JAX function of one state ``x`` and one input
  vector ``u`` (inputs interpolated at time ``t`` by the simulator); optionally written as
  ``vector_field_parts(t, xs, us) -> tuple`` on scalar components (``vector_field`` then stacks
  it), the form an augmented model (:class:`~diffship.models.effects.Augmented`) composes its
  effects in, so that no intermediate vector is stacked inside the time step (Fossen 3-DOF and
  MMG do; the others are split from the array form);
* ``observe(x, u) -> y`` — the measured channels the model predicts (``output_names``);
* ``initial_state(y0)`` — a state built from measured values at the first sample.

Models act on one trajectory; batching over runs or parameter sets is ``jax.vmap`` outside.
A model describes physics only: it imports nothing above :mod:`diffship.params` and
:mod:`diffship.errors` (no data handling, filtering or fitting).

**Parameters are declared once**, as fields made with :func:`param`::

    class Nomoto1(AbstractModel):
        K: jnp.ndarray = param(0.5, scale=0.5, unit="1/s", description="rudder gain")
        T1: jnp.ndarray = param(5.0, lower=0.0, scale=5.0, unit="s", description="yaw time constant")

``Model.PARAMS`` (and ``model.PARAMS``) is derived from those fields, in declaration order:
one :class:`~diffship.params.Param` each, its ``value`` the field default. A family that
declares every coefficient on one base class and uses a subset per member (the VMMs)
overrides :meth:`AbstractModel._select_params`. A subclass may still set ``PARAMS`` itself
(a class variable, or a property as :class:`diffship.diagnose.effects.Augmented` does);
fields made with :func:`scalar` are plain float64 fields that are not parameters.

**Equation-error form** (optional; what :func:`diffship.fit.fit_equation_error` needs). A
model declares which measured signals its equations use, and the equations themselves; the
fitter does all numerics (filtering, derivatives, trimming, stacking runs, least squares):

* ``EQUATION_CHANNELS`` — measured channels whose smoothed values ``z`` and time derivatives
  ``ż`` (and ``z̈`` when ``EQUATION_ORDER == 2``) the equations need, in column order;
* ``EQUATION_ORDER`` — the highest derivative needed (1 or 2);
* ``EQUATION_RATE_OF`` — ``{channel: source}``: a channel that is the time derivative of
  another (e.g. ``{"r": "psi"}``), used when the channel itself is not measured;
* ``EQUATION_INPUT_RATES`` — inputs whose smoothed time derivatives are appended to ``u``
  (e.g. the rudder rate ``δ̇`` for Nomoto 2's lead term);
* ``EQUATIONS`` — names of the entries of the residual;
* :meth:`AbstractModel.equation_residual` ``(z, zd, zdd, u) -> e`` — the equations at one
  sample, zero for the true parameters and noise-free signals;
* optionally :meth:`AbstractModel.regressors` ``(z, zd, zdd, u) -> {form: LinearForm}`` — a
  form linear in a set of coefficients, :math:`y = A c`, and
  :meth:`AbstractModel.from_regression` mapping the least-squares coefficients back to
  parameter values (the fitter's start).
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Mapping
from typing import Any, ClassVar, NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from ..errors import ModelError
from ..params import Param, ParamSpec, check_values

__all__ = ["AbstractModel", "LinearForm", "param", "parts", "scalar"]


def parts(v) -> tuple:
    """The components of a vector as a tuple of scalars (static slices); a tuple stays a tuple
    (``None``, no vector, stays ``None``): the form of :meth:`AbstractModel.vector_field_parts`."""
    if v is None or isinstance(v, tuple):
        return v
    return tuple(v[i] for i in range(v.shape[0]))


def _as_f64(v):
    return jnp.asarray(v, dtype=jnp.float64)


def scalar(default: float | None = None):
    """A float64 scalar field that is not a model parameter (see :func:`param`)."""
    if default is None:
        return eqx.field(converter=_as_f64)
    return eqx.field(converter=_as_f64, default=default)


def param(
    default: float,
    *,
    scale: float = 1.0,
    lower: float = -math.inf,
    upper: float = math.inf,
    free: bool = True,
    unit: str = "",
    description: str = "",
) -> Any:
    """A float64 scalar parameter field: the one declaration of a model parameter.

    Args:
        default: reference value (the field default and ``Param.value`` in ``PARAMS``).
        scale, lower, upper, free, unit, description: as in :class:`~diffship.params.Param`. A default
            on a bound (a zero added mass with the sign bound 0) makes that bound a value the model may
            hold (``Param.held_bounds``); a fit still starts inside it.
    """
    held = tuple(b for b in (lower, upper) if b == default)
    meta = Param("", float(default), free=free, lower=lower, upper=upper, scale=scale, unit=unit,
                 description=description, held_bounds=held)
    return eqx.field(converter=_as_f64, default=default, metadata={"param": meta})


@functools.cache
def _declared_params(cls: type) -> tuple[Param, ...]:
    found = {f.name: dataclasses.replace(f.metadata["param"], name=f.name)
             for f in dataclasses.fields(cls) if "param" in f.metadata}
    return tuple(found[n] for n in cls._select_params(tuple(found)))


class _DeclaredParams:
    """``PARAMS`` on classes and instances alike: derived from the :func:`param` fields."""

    def __get__(self, obj, owner) -> tuple[Param, ...]:
        return _declared_params(owner)


class LinearForm(NamedTuple):
    r"""Equations linear in a set of coefficients, :math:`y = A c`, broadcast over samples.

    Attributes:
        A: regressors, shape ``(..., k)``.
        y: regressand, shape ``(...)``.
        names: the ``k`` coefficient names (columns of ``A``).
    """

    A: Float[Array, "*n k"]
    y: Float[Array, "*n"]
    names: tuple[str, ...]


#: The rate state of each angle state: an angle fitted without its rate still determines the rate's start.
_RATE_OF_ANGLE = {"psi": "r", "phi": "p", "theta": "q"}


class AbstractModel(eqx.Module):
    """Base class: a vector field with named states, inputs, outputs and parameters.

    Subclasses set the class variables ``name``, ``state_names`` and ``output_names``,
    declare each parameter once as a :func:`param` field, and implement
    :meth:`vector_field` (and ``input_names``). See the module docstring for the optional
    equation-error form.
    """

    name: ClassVar[str] = "abstract"
    state_names: ClassVar[tuple[str, ...]] = ()
    output_names: ClassVar[tuple[str, ...]] = ()
    angle_outputs: ClassVar[tuple[str, ...]] = ("psi",)
    PARAMS: ClassVar[tuple[Param, ...]] = _DeclaredParams()  # type: ignore[assignment]
    #: Name of the published or standard parameter set the defaults are ("" for none); where
    #: set, fits use the defaults as loose priors on the reference vessel (diffship.fit.priors).
    REFERENCE: ClassVar[str] = ""

    # equation-error form (module docstring); empty EQUATIONS: none
    EQUATIONS: ClassVar[tuple[str, ...]] = ()
    EQUATION_CHANNELS: ClassVar[tuple[str, ...]] = ()
    EQUATION_ORDER: ClassVar[int] = 1
    EQUATION_RATE_OF: ClassVar[dict[str, str]] = {}
    EQUATION_INPUT_RATES: ClassVar[tuple[str, ...]] = ()

    # vessel particulars (see :mod:`diffship.vessel`); empty: the model needs none
    #: ``{parameter: vessel quantity}``: the parameters that are the vessel's particulars (mass,
    #: inertia, dimensions, density, approach speed, propeller and rudder data), each with the key of
    #: the quantity of a :class:`diffship.vessel.Vessel` that sets it (``diffship.vessel.QUANTITIES``).
    PARTICULARS: ClassVar[dict[str, str]] = {}
    #: The bundled vessel whose particulars are this model's default values (``--vessel NAME``).
    REFERENCE_VESSEL: ClassVar[str | None] = None
    #: Inputs that are a known constant when a run has no such column (e.g. zero force in a free decay).
    INPUT_DEFAULTS: ClassVar[dict[str, float]] = {}

    @classmethod
    def _select_params(cls, declared: tuple[str, ...]) -> tuple[str, ...]:
        """Which of the declared :func:`param` fields are this class's parameters (default: all)."""
        return declared

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

    def __check_init__(self):
        """A model built with concrete values holds only valid ones (:meth:`_check_values`); a model whose
        parameters are per instance (a ``PARAMS`` property, e.g. a base with effects) is checked in ``with_params``."""
        if isinstance(type(self).PARAMS, tuple):
            self._check_values({n: getattr(self, n) for n in self.param_names}, what="model value")

    def _check_values(self, values: Mapping[str, Any], what: str = "value") -> None:
        """:class:`ModelError` unless every concrete value is one finite number (``Param.check_held``; the bounds
        are the fit's, not the model's); traced values (inside ``jax.jit``/``vmap``) are not checked."""
        params = {p.name: p for p in self.PARAMS}
        for n, v in values.items():
            if not isinstance(v, jax.core.Tracer):
                try:
                    params[n].check_held(v, what, bounds=False)
                except ModelError as exc:
                    raise ModelError(f"model {self.name}: {exc}") from None

    def with_params(self, theta: Float[Array, " n_params"] | Mapping[str, float]) -> AbstractModel:
        """A copy with new parameter values (array in ``param_names`` order, or a mapping).

        Each value must be one finite number (``Param.check_held``; traced values are not checked; the bounds are a
        fit's, so a model may hold, say, a course-unstable T1 < 0); an array must have one entry per parameter.
        """
        names = self.param_names
        if isinstance(theta, Mapping):
            unknown = set(theta) - set(names)
            if unknown:
                raise ModelError(
                    f"model {self.name}: unknown parameter(s) {', '.join(sorted(unknown))}; it has {', '.join(names)}"
                )
            self._check_values(theta)
            new = {n: _as_f64(theta[n]) if n in theta else getattr(self, n) for n in names}
        else:
            if isinstance(theta, (str, bytes)):
                theta = [theta]
            shape = getattr(theta, "shape", None)
            size = (shape[0] if shape else -1) if shape is not None else len(theta)
            if size != len(names):
                given = f"{size} parameter value(s)" if size >= 0 else "a single number"
                raise ModelError(f"model {self.name}: {given} given, it has {len(names)} parameter(s) "
                                 f"({', '.join(names)}); give one value per parameter, in that order, or a mapping")
            if not isinstance(theta, jax.core.Tracer):
                host = theta if isinstance(theta, (list, tuple)) else np.asarray(theta)
                self._check_values({n: host[i] for i, n in enumerate(names)})
            new = {n: _as_f64(theta[i]) for i, n in enumerate(names)}
        return eqx.tree_at(lambda m: tuple(getattr(m, n) for n in names), self, tuple(new[n] for n in names))

    def with_vessel(self, vessel: Any) -> AbstractModel:
        """A copy with the particulars (:attr:`PARTICULARS`) set from a :class:`diffship.vessel.Vessel`.

        The vessel computes each value (e.g. the yaw inertia about this model's origin from a radius of
        gyration about the CG); a particular the vessel does not give raises :class:`ModelError`.
        """
        return vessel.apply(self)
    @classmethod
    def from_fit(cls, path) -> AbstractModel:
        """This model class with the parameter values of a fit file (``"schema": "diffship.fit/1"``).

        Reads only the values (plain JSON, no fitting code): ``diffship.load_fit(path)`` gives the
        whole fit (covariance, integrator, provenance). Fails if the file is another model's.
        """
        import json
        from pathlib import Path

        path = Path(path)
        try:
            doc = json.loads(path.read_text())
        except (OSError, ValueError) as exc:
            raise ModelError(f"{path}: cannot read a fit file ({exc})") from None
        if not isinstance(doc, dict) or doc.get("schema") != "diffship.fit/1":
            raise ModelError(f"{path}: not a diffship fit file (schema 'diffship.fit/1')")
        if doc.get("error"):  # the fit file of a command that stopped without a fit (diffship.fitfile.stopped_document)
            raise ModelError(f"{path}: holds no fit: the command that wrote it stopped without one ({doc['error']})")
        model = cls()
        name = doc.get("model", {}).get("name")
        if name != model.name:
            raise ModelError(f"{path}: holds a fit of model {name!r}, not {model.name!r}; use diffship.load_fit(path)")
        inputs = doc["model"].get("inputs")
        if inputs is not None and tuple(inputs) != tuple(model.input_names):
            raise ModelError(f"{path}: the fitted {name} has inputs {tuple(inputs)}, {cls.__name__}() has "
                             f"{model.input_names}; use diffship.load_fit(path)")
        check_values(str(path), doc.get("params"), model.param_names, model.name)  # present, finite, the model's
        return model.with_params(doc["params"])

    def canonical(self, values: Mapping[str, float]) -> dict[str, float]:
        """Relabel interchangeable parameters into a canonical order (identity unless overridden)."""
        return dict(values)

    # -- dynamics -------------------------------------------------------------------------
    def vector_field(self, t: Float[Array, ""], x: Float[Array, " n_x"], u: Float[Array, " n_u"]) -> Float[Array, " n_x"]:
        raise NotImplementedError

    def vector_field_parts(self, t: Float[Array, ""], xs: tuple, us: tuple) -> tuple:
        """:meth:`vector_field` on tuples of scalar components (what an augmented model calls,
        :class:`~diffship.models.effects.Augmented`); by default the array form, stacked and split.
        A model that writes this form natively keeps the integrator's time step free of stacked
        intermediate vectors, which XLA on a CPU runs as kernels of their own."""
        return parts(self.vector_field(t, jnp.stack(xs), jnp.stack(us)))

    def effect_twins(self) -> dict[str, str]:
        """Library effects (:mod:`diffship.models.effects`) this model carries as a parameter of
        its own, ``{effect name: parameter}`` — a rudder zero error is a Nomoto or MMG model's
        rudder neutral angle ``delta0``. Where the base fit estimates that parameter, the
        diagnosis reports the effect as in the base (:func:`diffship.diagnose.diagnose`, ``in_base``).
        Default: none."""
        return {}

    def observe(self, x: Float[Array, " n_x"], u: Float[Array, " n_u"]) -> Float[Array, " n_y"]:
        """Predicted measured channels; by default the states named in ``output_names``."""
        idx = [self.state_names.index(n) for n in self.output_names]
        return x[jnp.asarray(idx)]

    def initial_state(self, y0: Mapping[str, float]) -> np.ndarray:
        """State at the first sample from measured values (missing states start at 0)."""
        return np.array([float(y0.get(n, 0.0)) for n in self.state_names], dtype=np.float64)

    def states_for_channels(self, channels) -> tuple[str, ...]:
        """States whose initial values the fitted ``channels`` determine (the initial-state rule,
        :mod:`diffship.initial`): the measured states, and the rate of a fitted angle (ψ → r, φ → p,
        θ → q) that no channel measures — its initial value shapes the whole angle trace."""
        chosen = {c for c in channels if c in self.state_names}
        chosen |= {w for a, w in _RATE_OF_ANGLE.items() if a in channels and w in self.state_names}
        return tuple(s for s in self.state_names if s in chosen)

    # -- equation-error form (module docstring) -----------------------------------------------
    def equation_residual(
        self,
        z: Float[Array, " n_z"],
        zd: Float[Array, " n_z"],
        zdd: Float[Array, " n_z"],
        u: Float[Array, " n_u"],
    ) -> Float[Array, " n_eq"]:
        """Equation residual at one sample: ``z``, ``zd``, ``zdd`` hold the smoothed
        ``EQUATION_CHANNELS`` and their first and second time derivatives (``zdd`` is zero
        unless ``EQUATION_ORDER == 2``), ``u`` the inputs followed by ``EQUATION_INPUT_RATES``."""
        raise ModelError(f"model {self.name} has no equation-error form; use output error")

    def regressors(
        self,
        z: Float[Array, "*n n_z"],
        zd: Float[Array, "*n n_z"],
        zdd: Float[Array, "*n n_z"],
        u: Float[Array, "*n n_u"],
    ) -> dict[str, LinearForm]:
        """Linear regression form(s) of the equations (broadcast over leading sample axes); none by default."""
        return {}

    def from_regression(self, coefficients: Mapping[str, Mapping[str, float]]) -> dict[str, float] | None:
        """Parameter values from the least-squares coefficients of each form of :meth:`regressors`.

        Default: the coefficients are parameters of this model (merged over the forms).
        ``None``: the regression gives no usable values.
        """
        out: dict[str, float] = {}
        for coef in coefficients.values():
            out.update({n: float(v) for n, v in coef.items() if n in self.param_names})
        return out or None
