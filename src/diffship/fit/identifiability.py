r"""Identifiability of a fit: what the data pin down, what they do not, and what moved suspiciously.

Run on every output-error fit from the Jacobian at the optimum. The data rows are normalised by
their noise and the columns taken with respect to :math:`\theta_j/s_j` (each parameter in units
of its scale :math:`s_j`, :mod:`diffship.params`; not the fit's bounded variable ``z``, whose
log-maps make a parameter drifting towards its bound look like the whole problem):
:math:`\tilde J = J_d\,\mathrm{diag}(s_j\,\partial z_j/\partial\theta_j)/\hat\sigma`. The Fisher
information of the data is :math:`\tilde J^\top\tilde J = V\Sigma^2V^\top`; along the
right-singular vector :math:`v_k` the data determine :math:`\theta/s` to a standard deviation
:math:`1/\sigma_k`, and a direction with :math:`1/\sigma_k > 1` (more than one parameter scale) is
**poorly identified** and is written as a combination of named parameters,
e.g. ``0.71·Nrrr − 0.70·Nvvr``: moving the parameters along it barely changes the simulation.
Priors (:mod:`diffship.fit.priors`) are not in :math:`\tilde J`: the report says what the data
alone know, and the prior table says how much the prior added.

Warnings (also in ``FitResult.messages``):

* a poorly identified direction (named);
* a pair of parameters with :math:`|\rho| > 0.95` in the (posterior) covariance;
* a coefficient that moved by more than its own magnitude from its start (``|Δθ| > max(|θ₀|,
  scale)``), or more than 3 prior standard deviations from its prior mean;
* a coefficient whose sign differs from the model's reference value or from its start (a
  physical sign flip, such as a yaw damping term turning destabilising);
* a coefficient on one of its bounds (within :data:`ON_BOUND` of its scale): the data push it past what
  the model allows, so its standard error is no interval (a missing effect, or a bound to reconsider).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping

import numpy as np

from ..params import ParamSpec
from .priors import Priors

__all__ = ["Identifiability", "identifiability", "direction_text", "per_scale_columns"]

#: A direction whose data-only standard deviation in the scaled space exceeds this is "poor".
POOR = 1.0
#: Poorly identified directions named one by one in the warnings (the rest are counted).
MAX_NAMED = 3
#: Correlation magnitude above which a pair is reported.
CORRELATED = 0.95
#: A free parameter closer than this share of its scale to a finite bound is "on its bound".
ON_BOUND = 2e-3


@dataclasses.dataclass(frozen=True)
class Identifiability:
    """What the data identify (see the module docstring).

    Attributes:
        names: free parameters (column order).
        singular_values: of the noise-normalised scaled Jacobian, descending.
        condition: ``σ_max/σ_min`` (inf when rank deficient).
        weak: poorly identified directions: ``(data-only sd in scaled units, {name: component})``.
        correlated: ``(name_a, name_b, ρ)`` with ``|ρ| > 0.95``.
        moved: parameters that moved far from their start or prior: ``(name, start, value, why)``.
        sign_flips: ``(name, reference, value, against)`` — a sign different from the reference
            (``against="reference"``) or from the start.
        correlation: the correlation matrix of the free parameters (posterior).
        warnings: one sentence per finding.
        on_bound: ``(name, value, bound)`` of the parameters on a bound.
    """

    names: tuple[str, ...]
    singular_values: np.ndarray
    condition: float
    weak: tuple[tuple[float, dict[str, float]], ...]
    correlated: tuple[tuple[str, str, float], ...]
    moved: tuple[tuple[str, float, float, str], ...]
    sign_flips: tuple[tuple[str, float, float, str], ...]
    correlation: np.ndarray
    warnings: tuple[str, ...]
    on_bound: tuple[tuple[str, float, float], ...] = ()

    @property
    def ok(self) -> bool:
        return not self.warnings

    def as_json(self) -> dict:
        return {
            "singular_values": [float(s) for s in self.singular_values],
            "condition": self.condition if math.isfinite(self.condition) else "inf",
            "weak_directions": [{"sd_scaled": sd if math.isfinite(sd) else "inf", "direction": d,
                                 "text": direction_text(d)} for sd, d in self.weak],
            "correlated": [{"a": a, "b": b, "rho": rho} for a, b, rho in self.correlated],
            "moved": [{"name": n, "start": s, "value": v, "why": w} for n, s, v, w in self.moved],
            "sign_flips": [{"name": n, "reference": r, "value": v, "against": a} for n, r, v, a in self.sign_flips],
            "on_bound": [{"name": n, "value": v, "bound": b} for n, v, b in self.on_bound],
            "warnings": list(self.warnings),
        }


def direction_text(d: Mapping[str, float]) -> str:
    """``{"Nrrr": 0.71, "Nvvr": -0.70}`` → ``"0.71·Nrrr − 0.70·Nvvr"``."""
    parts = []
    for i, (n, c) in enumerate(sorted(d.items(), key=lambda kv: -abs(kv[1]))):
        sign = ("−" if c < 0 else "") if i == 0 else (" − " if c < 0 else " + ")
        parts.append(f"{sign}{abs(c):.2f}·{n}")
    return "".join(parts)


def per_scale_columns(spec: ParamSpec, z: np.ndarray, n_unknowns: int) -> np.ndarray:
    """Column factors turning a Jacobian in the fit variables ``(z_θ, extra)`` into one with
    respect to ``θ_j/s_j`` (extra unknowns unchanged): ``s_j / (∂θ_j/∂z_j)``."""
    n = len(spec.free_names)
    col = np.ones(n_unknowns)
    if n:
        scale = np.asarray([spec[m].scale for m in spec.free_names])
        dth = spec.dtheta_dz(np.asarray(z[:n], dtype=np.float64))
        tiny = np.finfo(float).tiny
        col[:n] = scale / np.where(np.abs(dth) > tiny, dth, tiny)
    return col


def _correlation(cov: np.ndarray) -> np.ndarray:
    d = np.sqrt(np.abs(np.diag(cov)))
    with np.errstate(invalid="ignore", divide="ignore"):
        c = cov / np.outer(d, d)
    c[~np.isfinite(c)] = np.nan
    np.fill_diagonal(c, 1.0)
    return c


def identifiability(
    J_scaled: np.ndarray,
    spec: ParamSpec,
    values: Mapping[str, float],
    cov: np.ndarray,
    *,
    start: Mapping[str, float] | None = None,
    start_label: str = "the start",
    priors: Priors | None = None,
    reference: Mapping[str, float] | None = None,
    component: float = 0.05,
) -> Identifiability:
    """Analyse a fit (see the module docstring).

    Args:
        J_scaled: noise-normalised data Jacobian with respect to ``θ_j/s_j`` ``(m, p)``
            (columns ``spec.free_names``; see :func:`per_scale_columns`).
        spec: the parameter spec.
        values: all fitted values; cov: posterior covariance of the free parameters (model units).
        start: the start values of the free parameters; priors, reference: to judge moves/signs.
        component: smallest |component| of a weak direction that is named.
    """
    names = spec.free_names
    p = len(names)
    J = np.asarray(J_scaled, dtype=np.float64)
    if p == 0 or J.size == 0:
        return Identifiability(names, np.zeros(0), math.nan, (), (), (), (), np.zeros((0, 0)), ())
    _, sv, vt = np.linalg.svd(J, full_matrices=False)
    tiny = sv[0] * 1e-12 if sv[0] > 0 else 1.0
    condition = float(sv[0] / sv[-1]) if sv[-1] > tiny else math.inf
    warnings: list[str] = []
    weak = []
    for k in range(len(sv) - 1, -1, -1):
        sd = 1.0 / sv[k] if sv[k] > tiny else math.inf
        if sd <= POOR:
            break
        v = vt[k] * (1.0 if vt[k][np.argmax(np.abs(vt[k]))] > 0 else -1.0)
        d = {names[i]: float(round(v[i], 3)) for i in range(p) if abs(v[i]) >= component}
        weak.append((float(sd), d))
    for sd, d in weak[:MAX_NAMED]:
        how = "not at all" if not math.isfinite(sd) else f"only to ±{sd:.3g} scale units"
        top = dict(sorted(d.items(), key=lambda kv: -abs(kv[1]))[:6])
        more = " …" if len(d) > len(top) else ""
        warnings.append(f"poorly identified direction: {direction_text(top)}{more} — the data determine it {how}; "
                        "fix one of these, give it a prior, or add a manoeuvre that excites it")
    if len(weak) > MAX_NAMED:
        warnings.append(f"{len(weak) - MAX_NAMED} further poorly identified direction(s) (all in the JSON): "
                        f"{len(weak)} of {p} directions rest on the priors or on nothing")
    corr = _correlation(np.asarray(cov, dtype=np.float64)) if np.size(cov) else np.zeros((0, 0))
    correlated = []
    for i in range(p):
        for j in range(i + 1, p):
            rho = corr[i, j]
            if np.isfinite(rho) and abs(rho) > CORRELATED:
                correlated.append((names[i], names[j], float(rho)))
                warnings.append(f"{names[i]} and {names[j]} are correlated (ρ = {rho:+.3f}): the data constrain "
                                "a combination of them better than either")
    moved, flips, on_bound = [], [], []
    for n in names:
        v = float(values[n])
        par = spec[n]
        on_bound += [(n, v, float(b)) for b in (par.lower, par.upper)
                     if math.isfinite(b) and abs(v - b) < ON_BOUND * par.scale]
        if start is not None and n in start:
            s0 = float(start[n])
            if abs(v - s0) > max(abs(s0), par.scale):
                moved.append((n, s0, v, f"moved {v - s0:+.3g} from {start_label} ({s0:.4g} → {v:.4g})"))
        if priors is not None and n in priors.by_name:
            pr = priors.by_name[n]
            zp = (v - pr.mean) / pr.sd
            if abs(zp) > 3:
                moved.append((n, pr.mean, v, f"{zp:+.1f} prior standard deviations from its prior mean {pr.mean:.4g}"))
        ref = None if reference is None else reference.get(n)
        if ref is not None and ref != 0 and v != 0 and math.copysign(1, ref) != math.copysign(1, v):
            flips.append((n, float(ref), v, "reference"))
        elif start is not None and n in start and start[n] != 0 and v != 0 \
                and math.copysign(1, start[n]) != math.copysign(1, v):
            flips.append((n, float(start[n]), v, "start"))
    for n, v, b in on_bound:
        warnings.append(f"{n} = {v:.4g} is on its bound {b:g}: the data push it past what the model allows, so its "
                        "standard error is no interval — look for a missing effect (diagnose) or reconsider the bound")
    for n, s0, v, why in moved:
        warnings.append(f"{n} {why}")
    for n, ref, v, against in flips:
        warnings.append(f"{n} changed sign against its {against} value ({ref:.4g} → {v:.4g}): check that "
                        "the fitted model is physically admissible outside the training runs")
    return Identifiability(names, sv, condition, tuple(weak), tuple(correlated), tuple(moved), tuple(flips),
                           corr, tuple(warnings), tuple(on_bound))
