r"""Scales of library-term coefficients: every coefficient of order one to the solver.

A term's coefficient :math:`\phi_t` multiplies its regressor :math:`g_t(u, v, r)` in its equation (X, Y or N). With
:math:`F_e` the force level of equation :math:`e` (the RMS of the measured generalised force, at least a tenth of the
largest: :func:`force_levels`), the scale

.. math::  s_t = 0.1\,F_e / \operatorname{RMS}(g_t)

is the coefficient that explains a tenth of the force: the solver works in :math:`\phi_t / s_t`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from ..data import Run
from ..models import AbstractModel
from ..models.terms import term_class
from ..params import ParamSpec

__all__ = ["force_levels", "term_scales", "term_spec"]


def term_scales(runs: Sequence[Run], terms: Sequence[str], level: dict[str, float]) -> dict[str, float]:
    """``{term: scale}``: a tenth of its equation's force level over the RMS of its regressor on ``runs`` (a term at
    one scale unit explains a tenth of the force), so that every coefficient is of order one to the solver."""
    u = np.concatenate([np.asarray(r["u"]) for r in runs])
    v = np.concatenate([np.asarray(r["v"]) if r.has("v") else np.zeros(r.n) for r in runs])
    r_ = np.concatenate([np.asarray(r["r"]) for r in runs])
    out = {}
    for t in terms:
        cls = term_class(t)
        out[t] = 0.1 * level[cls.equation] / (float(np.sqrt(np.mean(np.asarray(cls.regressor(u, v, r_)) ** 2))) or 1.0)
    return out


def term_spec(model: AbstractModel, base_spec: ParamSpec, runs: Sequence[Run], level: dict[str, float]) -> ParamSpec:
    """The spec of ``model`` (base with terms): ``base_spec`` followed by the terms, free, each scaled by
    :func:`term_scales`."""
    spec = model.spec(base_spec)
    scales = term_scales(runs, [p.name for p in spec.params if p.name not in base_spec], level)
    return ParamSpec(tuple(p if p.name in base_spec else dataclasses.replace(p, scale=scales[p.name])
                           for p in spec.params))


def force_levels(runs: Sequence[Run], model: AbstractModel) -> dict[str, float]:
    """Force level per equation: the RMS of the measured generalised force, at least a tenth of the largest."""
    out = {}
    for eq, name in zip(("X", "Y", "N"), ("tau_x", "tau_y", "tau_z")):
        vals = [np.asarray(r[name]) for r in runs if r.has(name)]
        out[eq] = float(np.sqrt(np.mean(np.concatenate(vals) ** 2))) if vals else 1.0
    top = max(out.values()) or 1.0
    return {k: max(v, 0.1 * top) for k, v in out.items()}
