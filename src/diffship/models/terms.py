r"""The term library of structure discovery: polynomial and modulus terms in the body velocities.

A *term* is one added generalised force in one equation of a 3-DOF model,

.. math::
    \Delta\tau_j = c_{j,k}\,\phi_k(u, v, r), \qquad j \in \{X, Y, N\},

with :math:`\phi_k` a product of up to three factors from :math:`u, v, r, |u|, |v|, |r|`
(:math:`vr`, :math:`r^2`, :math:`r|r|`, :math:`v^2 r`, :math:`r^3`, ...). A model with terms is
:class:`~diffship.models.effects.Augmented` with one :class:`Term` effect per term (the ``force``
hook: :math:`\dot\nu = \dot\nu_{base} + M^{-1}\Delta\tau`, the base model's own mass matrix), so it
is an ordinary diffship model: it fits with the driver, simulates, and is saved and read back by its
base model's registry key plus the term names (:func:`with_terms`, :mod:`diffship.fitfile`).

**Names.** A term is named ``<equation>_<factors>``, e.g. ``N_v_r`` (:math:`N_{vr}\,vr`), ``Y_r_ar``
(:math:`Y_{r|r|}\,r|r|`), ``N_v_v_r`` (:math:`N_{vvr}\,v^2 r`): factors ``u, v, r`` and ``au, av, ar``
for their moduli, in the order u, v, r, au, av, ar. The name is also the coefficient's parameter name
(fossen3's own ``Xuu, Yvv, Nrr, ...`` have no underscore, so names never clash). An expression is
accepted too (:func:`parse_term`): ``"N: v*r"``, ``"Y:r|r|"``, ``"N: v^2 r"``.

**Libraries** (:data:`LIBRARIES`): ``symmetric`` (default) keeps only the terms a port–starboard
symmetric hull can have — even in :math:`(v, r)` in surge, odd in sway and yaw (Fossen 2021, §6.4; the
same argument gives Abkowitz's expansion its shape, Abkowitz 1964) — and drops those that duplicate a
base parameter (``Y_v_av`` is fossen3's ``Yvv``) or its Coriolis/Munk terms (``X_v_r``, ``Y_u_r``,
``N_u_v``); ``all`` has every product up to third order in each equation.

Each coefficient's unit is the equation's force unit over the term's; its declared ``scale`` (100) is
a placeholder: structure discovery sets scales from the data (force RMS over term RMS).

References: T. I. Fossen, *Handbook of Marine Craft Hydrodynamics and Motion Control*, 2nd ed., Wiley
2021, §6.4; M. A. Abkowitz, *Lectures on ship hydrodynamics — steering and manoeuvrability*, Hy-5,
1964.
"""

from __future__ import annotations

import functools
import re
from collections.abc import Sequence
from typing import ClassVar

import jax.numpy as jnp

from ..errors import ModelError
from ._base import AbstractModel
from .effects import Augmented, Effect, is_ship3
from .effects._base import body_velocity, param

__all__ = ["Term", "EQUATIONS", "FACTORS", "LIBRARIES", "term_class", "parse_term", "library_terms", "with_terms",
           "terms_of", "base_of", "term_label", "term_values"]

#: The equations of a 3-DOF model a term may enter, and their force units.
EQUATIONS: dict[str, str] = {"X": "N", "Y": "N", "N": "N m"}
#: Factors in canonical order; ``a`` + variable is its modulus.
FACTORS: tuple[str, ...] = ("u", "v", "r", "au", "av", "ar")
_UNIT = {"u": "m/s", "v": "m/s", "r": "rad/s"}


def _order(factors: Sequence[str]) -> tuple[str, ...]:
    return tuple(sorted(factors, key=FACTORS.index))


def _odd_in_vr(factors: Sequence[str]) -> bool:
    """A monomial changes sign with (v, r) → (−v, −r) when it has an odd number of signed v, r factors."""
    return sum(f in ("v", "r") for f in factors) % 2 == 1


class Term(Effect):
    r"""One library term :math:`c\,\phi(u, v, r)` added to one equation (module docstring).

    Subclasses are made by :func:`term_class` (one per name, cached): each declares its coefficient
    once, as a :func:`~diffship.models.param` field named after the term, null value 0."""

    family: ClassVar[str] = "term"
    equation: ClassVar[str] = "N"
    factors: ClassVar[tuple[str, ...]] = ()
    signature: ClassVar[str] = "a force that grows with a power of the velocities not in the base model"
    separating: ClassVar[str] = "manoeuvres that span the velocities the term depends on (large v and r together)"

    @classmethod
    def applicability(cls, base, runs=None) -> str:
        return "" if is_ship3(base) else f"{base.name} is not a 3-DOF model (terms act on surge, sway and yaw)"

    @property
    def coefficient(self) -> jnp.ndarray:
        return getattr(self, self.name)

    @classmethod
    def regressor(cls, u, v, r):
        r""":math:`\phi(u, v, r)` (broadcasts over arrays)."""
        vals = {"u": u, "v": v, "r": r, "au": jnp.abs(u), "av": jnp.abs(v), "ar": jnp.abs(r)}
        out = jnp.ones_like(u)
        for f in cls.factors:
            out = out * vals[f]
        return out

    def force_parts(self, base, t, xb, ub, uext):
        u, v, r = body_velocity(base, xb)
        q = self.coefficient * self.regressor(u, v, r)
        z = jnp.zeros_like(q)
        return tuple(q if self.equation == e else z for e in EQUATIONS)


def term_label(name: str) -> str:
    """A readable form of a term name: ``N_v_ar`` → ``N: v|r|``."""
    eq, factors = _split(name)
    txt = "".join(f"|{f[1]}|" if f.startswith("a") else f for f in factors)
    return f"{eq}: {txt}"


def _split(name: str) -> tuple[str, tuple[str, ...]]:
    eq, _, rest = name.partition("_")
    factors = tuple(rest.split("_")) if rest else ()
    if eq not in EQUATIONS or not factors or any(f not in FACTORS for f in factors) or len(factors) > 3:
        raise ModelError(f"unknown term {name!r}: a term is EQ_F1[_F2[_F3]] with EQ one of X, Y, N and factors "
                         f"from {', '.join(FACTORS)} (au = |u|), e.g. N_v_r, Y_r_ar, N_v_v_r; or an expression "
                         "such as 'N: v*r' or 'Y: r|r|'")
    if _order(factors) != factors:
        raise ModelError(f"term {name!r}: write its factors in the order {', '.join(FACTORS)} "
                         f"({eq}_{'_'.join(_order(factors))})")
    return eq, factors


@functools.cache
def term_class(name: str) -> type[Term]:
    """The :class:`Term` subclass of a term name (one class per name, so compiled programs are reused)."""
    eq, factors = _split(name)
    unit = "·".join(_UNIT[f.lstrip("a")] for f in factors)
    ns = {"__annotations__": {name: jnp.ndarray},
          name: param(0.0, scale=100.0, unit=f"{EQUATIONS[eq]}/({unit})", description=f"term {term_label(name)}"),
          "name": name, "equation": eq, "factors": factors, "__module__": __name__,
          "__doc__": f"Library term {term_label(name)} (null value 0)."}
    return type(f"Term_{name}", (Term,), ns)


_EXPR = re.compile(r"^\s*([XYN])\s*[:=]\s*(.+)$")


def parse_term(text: str) -> str:
    """The canonical name of a term given by name (``N_v_r``) or expression (``N: v*r``, ``Y:r|r|``,
    ``N: v^2 r``, ``N: v r^2``); :class:`~diffship.errors.ModelError` if it is neither."""
    text = text.strip()
    m = _EXPR.match(text)
    if not m:
        eq, factors = _split(text) if "_" in text else _split(text + "_")
        return f"{eq}_{'_'.join(factors)}"
    eq, body = m.group(1), m.group(2).replace(" ", "").replace("*", "").replace("·", "")
    factors: list[str] = []
    for tok, power in re.findall(r"(\|[uvr]\||[uvr])(?:\^(\d))?", body):
        f = "a" + tok[1] if tok.startswith("|") else tok
        factors += [f] * int(power or 1)
    if not factors or re.sub(r"(\|[uvr]\||[uvr])(\^\d)?", "", body):
        raise ModelError(f"term {text!r}: cannot read the expression; use products of u, v, r, |u|, |v|, |r| "
                         "with ^ for powers, e.g. 'N: v*r', 'Y: r|r|', 'N: v^2 r'")
    name = f"{eq}_{'_'.join(_order(factors))}"
    _split(name)
    return name


# what the base fossen3 already has (parameters or Coriolis/Munk terms), per equation
_IN_BASE = {"X": {("au", "u"), ("u", "au"), ("v", "r"), ("u", "u"), ("u", "au")},
            "Y": {("v", "av"), ("u", "r")}, "N": {("r", "ar"), ("u", "v")}}
_QUADRATIC = [("u", "v"), ("u", "r"), ("v", "v"), ("v", "r"), ("r", "r"), ("v", "av"), ("v", "ar"), ("r", "av"),
              ("r", "ar"), ("u", "au")]
_CUBIC = [("v", "v", "v"), ("v", "v", "r"), ("v", "r", "r"), ("r", "r", "r")]


def _library(symmetric: bool) -> tuple[str, ...]:
    out = []
    for eq in EQUATIONS:
        for f in _QUADRATIC + _CUBIC:
            f = _order(f)
            if f in _IN_BASE[eq] or (eq == "X" and f[0] == "u" and len(f) == 2 and f[1] in ("u", "au")):
                continue
            if symmetric and _odd_in_vr(f) != (eq != "X"):
                continue
            out.append(f"{eq}_{'_'.join(f)}")
    return tuple(out)


#: Named libraries (module docstring).
LIBRARIES: dict[str, tuple[str, ...]] = {"symmetric": _library(True), "all": _library(False)}


def library_terms(spec: str | Sequence[str] = "symmetric") -> tuple[str, ...]:
    """Term names of a library: a name in :data:`LIBRARIES`, or items (library names, term names,
    expressions; a string is split at commas and semicolons), duplicates dropped in order."""
    items = [s for s in re.split(r"[;,]", spec)] if isinstance(spec, str) else list(spec)
    out: list[str] = []
    for item in (i.strip() for i in items):
        if not item:
            continue
        names = LIBRARIES[item] if item in LIBRARIES else (parse_term(item),)
        out += [n for n in names if n not in out]
    if not out:
        raise ModelError(f"empty term library {spec!r}: name terms (N_v_r, 'Y: r|r|') or a library "
                         f"({', '.join(LIBRARIES)})")
    return tuple(out)


def with_terms(base: AbstractModel, names: Sequence[str] = (), values: dict[str, float] | None = None) -> AbstractModel:
    """``base`` with the library terms ``names`` (at ``values``, else 0): an :class:`Augmented` model
    (``base`` itself when there are none)."""
    names = [parse_term(n) for n in names]
    if not names:
        return base
    if not is_ship3(base):
        raise ModelError(f"terms act on 3-DOF models (surge, sway, yaw); {base.name} is not one")
    m = Augmented(base, [term_class(n)() for n in names])
    vals = {n: v for n, v in (values or {}).items() if n in names}
    return m.with_params(vals) if vals else m


def terms_of(model: AbstractModel) -> tuple[str, ...]:
    """The library terms of a model (``()`` for a model without terms)."""
    return tuple(e.name for e in getattr(model, "effects", ()) if isinstance(e, Term))


def base_of(model: AbstractModel) -> AbstractModel:
    """The base model of a model with terms (the model itself otherwise)."""
    return model.base if terms_of(model) and len(terms_of(model)) == len(model.effects) else model


def term_values(model: AbstractModel) -> dict[str, float]:
    """``{term: coefficient}`` of a model with terms."""
    vals = model.param_values()
    return {n: vals[n] for n in terms_of(model)}
