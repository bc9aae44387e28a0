"""Named model parameters: value, free/fixed, bounds and scale.

A model is an :class:`equinox.Module` whose parameters are scalar fields (``m``, ``Xu``, ``K``,
...). What a fit needs to know about them beyond their values lives here, in a
:class:`ParamSpec`: which are free, their bounds, their typical magnitude (scale), their unit.

Fits run in a *scaled, unconstrained* space ``z`` (one entry per free parameter)::

    no bounds        θ = s·z
    lower bound a    θ = a + s·exp(z)
    upper bound b    θ = b − s·exp(z)
    both a < b       θ = a + (b − a)·sigmoid(z)

so that every entry of ``z`` is O(1) near the solution (Levenberg–Marquardt damps with λI and
does not converge on raw hydrodynamic coefficients that span eight orders of magnitude), and
sign constraints such as ``X_u < 0`` hold by construction (a bounded value never rounds onto its
bound: deep in the tail it stays one representable number inside). Standard errors are mapped back by
the delta method, ``σ_θ = |dθ/dz|·σ_z``.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .errors import DataError, ModelError

__all__ = ["Param", "ParamSpec", "check_values", "parse_assignments", "values_from_z"]

_LINEAR, _LOWER, _UPPER, _BOTH = 0, 1, 2, 3


@dataclasses.dataclass(frozen=True)
class Param:
    """One named parameter.

    Attributes:
        name: identifier, e.g. ``"Xu"`` (SNAME notation) or ``"T1"``.
        value: current value in the model's SI units.
        free: estimated by a fit (``True``) or held at ``value`` (``False``).
        lower, upper: open bounds (``±inf`` for none). A value on a bound is rejected.
        scale: typical magnitude, used to scale the fit variable (must be > 0).
        unit: SI unit, for reports.
        description: one line for reports.
        held_bounds: the bounds a model may hold as a value (not a fit start): those the declared
            value sits on, e.g. a zero added mass whose sign bound is 0 (:func:`~diffship.models.param`).
    """

    name: str
    value: float
    free: bool = True
    lower: float = -math.inf
    upper: float = math.inf
    scale: float = 1.0
    unit: str = ""
    description: str = ""
    held_bounds: tuple[float, ...] = ()

    def __post_init__(self):
        if not self.scale > 0 or not math.isfinite(self.scale):
            raise ModelError(f"parameter {self.name}: scale must be a positive finite number, got {self.scale}")
        if not self.lower < self.upper:
            raise ModelError(f"parameter {self.name}: lower bound {self.lower} must be below upper bound {self.upper}")

    @property
    def kind(self) -> int:
        lo, hi = math.isfinite(self.lower), math.isfinite(self.upper)
        return _BOTH if lo and hi else _LOWER if lo else _UPPER if hi else _LINEAR

    def check_held(self, value: Any, what: str = "value", bounds: bool = True) -> float:
        """``value`` as a float, or :class:`ModelError` unless it is one finite number (``bounds``: within the bounds).

        The bounds are open: a value on one is refused unless it is one of :attr:`held_bounds`. With ``bounds``,
        what a fixed parameter of a fit may hold (a fit's start is :meth:`check_value`); a model itself may hold any
        finite value (``bounds=False``: the bounds are the fit's, and a simulation may ask what a course-unstable
        ship with T1 < 0 or a destabilising term does).
        """
        try:
            v = np.asarray(value, dtype=np.float64)
        except (TypeError, ValueError):
            v = None
        if v is None or v.ndim != 0 or isinstance(value, (str, bytes)):
            raise ModelError(f"parameter {self.name}: {what} {value!r} is not a number; give one finite number")
        v = float(v)
        if not math.isfinite(v):
            raise ModelError(f"parameter {self.name}: {what} {v} is not finite; give one finite number")
        if bounds and not (self.lower < v < self.upper or v in self.held_bounds):
            raise ModelError(
                f"parameter {self.name}: {what} {v:g} {self.unit} is not strictly inside its bounds ({self.lower:g}, "
                f"{self.upper:g}) (a value on a bound is refused); give a value inside them"
            )
        return v

    def check_value(self, value: float, what: str = "value") -> None:
        """Raise :class:`ModelError` unless ``value`` is finite and strictly inside the bounds."""
        if not math.isfinite(value):
            raise ModelError(f"parameter {self.name}: {what} {value} is not finite")
        if self.free and not (self.lower < value < self.upper):
            raise ModelError(
                f"parameter {self.name}: {what} {value:g} {self.unit} is not strictly inside its bounds "
                f"({self.lower:g}, {self.upper:g}); start from a value inside them, or fix it with "
                f"--fix {self.name}=VALUE"
            )


@dataclasses.dataclass(frozen=True)
class ParamSpec:
    """An ordered, immutable set of :class:`Param`.

    Hashable: :meth:`structural` (values zeroed) is the key used to share compiled fits between
    problems that differ only in parameter values.
    """

    params: tuple[Param, ...]

    def __post_init__(self):
        names = [p.name for p in self.params]
        if len(set(names)) != len(names):
            raise ModelError(f"duplicate parameter names in {names}")

    # -- access ------------------------------------------------------------------------
    @property
    def names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.params)

    @property
    def free_names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.params if p.free)

    @property
    def fixed_names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.params if not p.free)

    def __getitem__(self, name: str) -> Param:
        for p in self.params:
            if p.name == name:
                return p
        raise ModelError(f"unknown parameter {name!r}; this model has: {', '.join(self.names)}")

    def __contains__(self, name: str) -> bool:
        return name in self.names

    def values(self) -> dict[str, float]:
        return {p.name: p.value for p in self.params}

    def structural(self) -> ParamSpec:
        """The same spec with every value set to 0: equal for problems that differ only in values."""
        return ParamSpec(tuple(dataclasses.replace(p, value=0.0) for p in self.params))

    def nudged(self, values: Mapping[str, float]) -> tuple[dict[str, float], list[str]]:
        """Move free start values that sit on (or beyond) a bound just inside it.

        A reference value of exactly zero for a sign-constrained derivative (e.g. the zero added
        masses of the seed-002 USV) cannot start a log-scaled fit; it becomes ``−0.01·scale``.
        Returns the new values and one note per change.
        """
        out, notes = dict(values), []
        for p in self.params:
            if not p.free:
                continue
            v = float(out[p.name])
            if p.lower < v < p.upper:
                continue
            if p.kind == _BOTH:
                new = 0.5 * (p.lower + p.upper)
            elif p.kind == _LOWER:
                new = p.lower + 0.01 * p.scale
            else:
                new = p.upper - 0.01 * p.scale
            out[p.name] = new
            notes.append(f"start value of {p.name} ({v:g}) moved inside its bound to {new:g}")
        return out, notes

    # -- functional updates ---------------------------------------------------------------
    def _replace(self, name: str, **changes) -> ParamSpec:
        self[name]  # raises a clear error for unknown names
        return ParamSpec(tuple(dataclasses.replace(p, **changes) if p.name == name else p for p in self.params))

    def with_values(self, values: Mapping[str, float]) -> ParamSpec:
        spec = self
        for name, v in values.items():
            spec = spec._replace(name, value=float(v))
        return spec

    def fix(self, values: Mapping[str, float] | Iterable[str]) -> ParamSpec:
        """Hold parameters fixed, optionally at new values (a mapping) or at their current ones.

        A new value must be one finite number within the parameter's bounds (:meth:`Param.check_held`).
        """
        if isinstance(values, Mapping):
            values = {n: self[n].check_held(v, "fixed value") for n, v in values.items()}
            spec = self.with_values(values)
            names = list(values)
        else:
            spec, names = self, list(values)
            for n in names:
                self[n].check_held(self[n].value, "fixed value")
        for n in names:
            spec = spec._replace(n, free=False)
        return spec

    def with_bounds(self, name: str, lower: float | None = None, upper: float | None = None) -> ParamSpec:
        """The spec with new open bounds for ``name`` (``None`` keeps a bound)."""
        p = self[name]
        return self._replace(name, lower=p.lower if lower is None else float(lower),
                             upper=p.upper if upper is None else float(upper))

    def free(self, names: Iterable[str]) -> ParamSpec:
        spec = self
        for n in names:
            spec = spec._replace(n, free=True)
        return spec

    def only_free(self, names: Iterable[str]) -> ParamSpec:
        """Free exactly ``names``; fix every other parameter at its current value."""
        names = set(names)
        for n in names:
            self[n]
        return ParamSpec(tuple(dataclasses.replace(p, free=p.name in names) for p in self.params))

    # -- scaled space -----------------------------------------------------------------
    def free_arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(kind, lower, upper, scale)`` of the free parameters, in order (NumPy; an infinite bound
        is 0, its kind says it is absent): the arrays of :func:`values_from_z`."""
        free = [p for p in self.params if p.free]
        kind = np.array([p.kind for p in free], dtype=np.int64)
        lo = np.array([p.lower if math.isfinite(p.lower) else 0.0 for p in free])
        hi = np.array([p.upper if math.isfinite(p.upper) else 0.0 for p in free])
        s = np.array([p.scale for p in free])
        return kind, lo, hi, s

    def free_index(self) -> np.ndarray:
        return np.array([i for i, p in enumerate(self.params) if p.free], dtype=np.int64)

    def to_z(self, values: Mapping[str, float] | None = None) -> np.ndarray:
        """Scaled unconstrained vector of the free parameters (NumPy, float64)."""
        vals = self.values() if values is None else {**self.values(), **values}
        out = []
        for p in self.params:
            if not p.free:
                continue
            v = float(vals[p.name])
            p.check_value(v, "start value")
            k = p.kind
            if k == _LINEAR:
                out.append(v / p.scale)
            elif k == _LOWER:
                out.append(math.log((v - p.lower) / p.scale))
            elif k == _UPPER:
                out.append(math.log((p.upper - v) / p.scale))
            else:
                f = (v - p.lower) / (p.upper - p.lower)
                out.append(math.log(f / (1.0 - f)))
        return np.asarray(out, dtype=np.float64)

    def from_z(self, z: Float[Array, " n_free"]) -> Float[Array, " n_free"]:
        """Free parameter values (model units) from the scaled vector; jittable."""
        kind, lo, hi, s = self.free_arrays()
        if kind.size == 0:
            return jnp.zeros((0,), dtype=z.dtype)
        return values_from_z(z, kind, lo, hi, s)

    def dtheta_dz(self, z: np.ndarray) -> np.ndarray:
        """Derivative of each free value with respect to its scaled variable (NumPy)."""
        kind, lo, hi, s = self.free_arrays()
        z = np.asarray(z, dtype=np.float64)
        ez = np.exp(np.clip(z, -50, 50))
        sig = 1.0 / (1.0 + np.exp(-np.clip(z, -50, 50)))
        return np.where(
            kind == _LINEAR, s, np.where(kind == _LOWER, s * ez, np.where(kind == _UPPER, -s * ez, (hi - lo) * sig * (1 - sig)))
        )

    def full_values(self, z: Float[Array, " n_free"], base: Float[Array, " n"]) -> Float[Array, " n"]:
        """All parameter values: ``base`` (all values) with the free entries taken from ``z``."""
        idx = self.free_index()
        if idx.size == 0:
            return base
        return base.at[idx].set(self.from_z(z))


def values_from_z(z: Float[Array, " n_free"], kind, lo, hi, s) -> Float[Array, " n_free"]:
    r"""The map from the scaled vector to parameter values, with the spec's arrays as arguments.

    Per free parameter of scale :math:`s`: linear :math:`\theta = s z`; a lower bound
    :math:`\theta = l + s e^{z}`; an upper bound :math:`\theta = h - s e^{z}`; both
    :math:`\theta = l + (h - l)\,\sigma(z)`. ``kind``, ``lo``, ``hi`` and ``s`` are
    :meth:`ParamSpec.free_arrays` (NumPy constants in :meth:`ParamSpec.from_z`; arrays that a
    compiled program takes as data where one program serves several spaces, e.g. the equation-error
    fit's linear and bounded spaces). Jittable.
    """
    # Clamp the exponent argument so that a wild trial step cannot overflow to inf; a value never rounds onto its
    # bound (deep in the tail, l + s·e^z == l in floating point: a fit file's value on its bound could not start a
    # later fit), it stays one representable number inside.
    # Outside a trace (concrete values, e.g. a start converted on the host) the same formulas run in NumPy: JAX would
    # compile each operation for each new shape, seconds of a fit's first call in a new process.
    concrete = not any(isinstance(a, jax.core.Tracer) for a in (z, kind, lo, hi, s))
    xp = np if concrete else jnp
    if concrete:
        z, lo, hi, s = (np.asarray(a, dtype=np.float64) for a in (z, lo, hi, s))
        kind = np.asarray(kind)
    with np.errstate(all="ignore"):  # the branches not taken may be inf − inf (NumPy warns; JAX does not)
        ez = xp.exp(xp.clip(z, -50.0, 50.0))
        lin = s * z
        inside_lo, inside_hi = xp.nextafter(lo, xp.inf), xp.nextafter(hi, -xp.inf)
        lower = xp.maximum(lo + s * ez, inside_lo)
        upper = xp.minimum(hi - s * ez, inside_hi)
        both = xp.clip(lo + (hi - lo) * (1.0 / (1.0 + xp.exp(-xp.clip(z, -50.0, 50.0)))), inside_lo, inside_hi)
        out = xp.where(kind == _LINEAR, lin, xp.where(kind == _LOWER, lower, xp.where(kind == _UPPER, upper, both)))
    return jnp.asarray(out) if concrete else out


def parse_assignments(items: Sequence[str] | None, what: str = "--fix") -> dict[str, float]:
    """Parse ``["NAME=VALUE", ...]`` from the command line into a dict of floats."""
    out: dict[str, float] = {}
    for item in items or ():
        name, sep, value = item.partition("=")
        if not sep or not name.strip():
            raise ModelError(f"{what} {item!r}: expected NAME=VALUE, e.g. {what} T1=5.0")
        try:
            out[name.strip()] = float(value)
        except ValueError:
            raise ModelError(f"{what} {item!r}: {value!r} is not a number") from None
    return out


def check_values(where: str, values, names: Sequence[str], owner: str) -> None:
    """``values`` (a fit file's ``params``, read at ``where``) holds a finite number for every parameter ``names`` of
    model ``owner`` and nothing else; a :class:`DataError` naming the place and the parameter otherwise."""
    if not isinstance(values, Mapping):
        raise DataError(f"{where}: no parameter values ('params': {{name: value}}); the file is not a complete fit "
                        "file: write it again with python -m diffship.fit ... --out DIR or --save FILE")
    if unknown := sorted(set(values) - set(names)):
        raise DataError(f"{where}: parameter(s) {', '.join(unknown)} are not parameters of model {owner}")
    for name, v in values.items():
        if not (isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)):
            raise DataError(f"{where}: parameter {name} = {v!r} is not a finite number; correct it in 'params' "
                            "or fit again")
    if missing := [n for n in names if n not in values]:
        raise DataError(f"{where}: parameter(s) {', '.join(missing)} of model {owner} missing from 'params' (a fit "
                        f"file holds every parameter of its model): is {owner} the model these values are for? Fit "
                        "again, or give the missing values")

