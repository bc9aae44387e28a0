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

**Libraries** (:data:`LIBRARIES`). ``all`` has every product of :math:`u, v, r` and their moduli up
to third order in each equation: for each variable with exponent :math:`k \ge 1` the two distinct
functions :math:`x^k` and :math:`x^{k-1}|x|` (:math:`|x|^2 = x^2`, so no other product is new), 43
monomials per equation, less those that duplicate a base parameter exactly: ``X_u`` (fossen3's
``Xu``), ``X_u_au`` and ``X_u_u`` (``Xuu``: equal wherever :math:`u > 0`), ``Y_v``, ``Y_r``,
``Y_v_av``, ``N_v``, ``N_r``, ``N_r_ar``. The surge speed enters with its sign only (``u``, never
``au``): manoeuvring data of a surface vessel have :math:`u > 0`, where :math:`|u|^k` and
:math:`u^k` are the same regressor and a library with both holds exactly collinear pairs (a name
with ``au`` is still accepted). ``symmetric`` (default) keeps the terms a port–starboard symmetric
hull can have: the mirror image :math:`(v, r, Y, N) \to (-v, -r, -Y, -N)` leaves the equations
unchanged only if the surge terms are even in :math:`(v, r)` and the sway and yaw terms odd (Fossen
2021, §6.4; the same argument gives Abkowitz's expansion its shape, Abkowitz 1964) — ``X_v_r``,
``X_v_v``, ``X_av``, ``Y_v_v_r``, ``Y_u_r``, ``N_v_r_r``, ``N_r_r_r``, ``N_u_v``, ``N_v_ar``, ...

**Monomials that the rigid-body and added-mass terms carry are in the libraries.** fossen3's
:math:`C(\nu)\nu = C_{RB}(\nu)\nu + C_A(\nu)\nu` holds

.. math::
    X:\ -(m - Y_{\dot v})\,vr - (m x_g - \tfrac12(N_{\dot v} + Y_{\dot r}))\,r^2, \qquad
    Y:\ (m - X_{\dot u})\,ur, \qquad
    N:\ (X_{\dot u} - Y_{\dot v})\,uv + (m x_g - \tfrac12(N_{\dot v} + Y_{\dot r}))\,ur,

so :math:`vr` in surge, :math:`ur` in sway and :math:`uv` (the Munk moment) in yaw are already
there — but each with a coefficient tied to the masses, which the fit also needs for the
accelerations (:math:`M\dot\nu`) and, with :math:`m` known, cannot move freely. A hull's own
hydrodynamic :math:`X_{vr}\,vr` (lift-induced surge force in a turn, Abkowitz's :math:`X_{vr}`),
:math:`Y_{ur}\,ur` or :math:`N_{uv}\,uv` is a coefficient *beside* the tied one; without
``X_v_r`` in the library a model with that physics can only be approximated by stand-ins (on the
USV truths :math:`X_{vv}v^2 + X_{rr}r^2`), which predict worse off the training manoeuvres. The
terms ``X_v_r``, ``X_r_r``, ``Y_u_r``, ``N_u_v`` and ``N_u_r`` are therefore terms of their own
(:math:`\Delta\tau_X = X_{vr}vr` adds to :math:`-C(\nu)\nu`; the sum's coefficient
:math:`X_{vr} + m - Y_{\dot v}` is what the data determine, the added mass being fixed by the
accelerations). Only pure duplicates of base parameters are left out.

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
           "terms_of", "base_of", "term_label", "term_values", "monomials"]

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
    if _canonical(factors) != factors:
        raise ModelError(f"term {name!r} is the same function as {eq}_{'_'.join(_canonical(factors))} "
                         "(|x|·|x| = x·x): use that name")
    return eq, factors


def _canonical(factors: Sequence[str]) -> tuple[str, ...]:
    r"""The one name of a monomial: per variable :math:`x^{k-m}|x|^m` is :math:`x^k` for even m and
    :math:`x^{k-1}|x|` for odd m."""
    out: list[str] = []
    for x in ("u", "v", "r"):
        k, m = sum(f in (x, "a" + x) for f in factors), sum(f == "a" + x for f in factors)
        out += [x] * (k - m % 2) + ["a" + x] * (m % 2)
    return _order(out)


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
    name = f"{eq}_{'_'.join(_canonical(factors))}"
    _split(name)
    return name


# monomials that are exactly a base (fossen3) parameter's, per equation: left out of every library
_DUPLICATES = {"X": {("u",), ("u", "au"), ("u", "u")}, "Y": {("v",), ("r",), ("v", "av")},
               "N": {("v",), ("r",), ("r", "ar")}}


def _forms(x: str, k: int) -> list[tuple[str, ...]]:
    """The distinct functions of degree ``k`` in one variable: :math:`x^k` and :math:`x^{k-1}|x|`
    (``u`` only signed: module docstring)."""
    if k == 0:
        return [()]
    return [(x,) * k] + ([] if x == "u" else [(x,) * (k - 1) + ("a" + x,)])


def monomials(max_degree: int = 3) -> list[tuple[str, ...]]:
    """Every distinct product of u, v, r and |v|, |r| of degree 1..``max_degree``, lowest degree first,
    canonical factor order (module docstring)."""
    out = []
    for deg in range(1, max_degree + 1):
        for a in range(deg, -1, -1):
            for b in range(deg - a, -1, -1):
                c = deg - a - b
                out += [_order(("u",) * a + fv + fr) for fv in _forms("v", b) for fr in _forms("r", c)]
    return out


def _library(symmetric: bool) -> tuple[str, ...]:
    out = []
    for eq in EQUATIONS:
        for f in monomials(3):
            if f in _DUPLICATES[eq] or (symmetric and _odd_in_vr(f) != (eq != "X")):
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
