r"""Priors on model parameters: regularised output error and maximum a posteriori estimates.

A parameter may carry a Gaussian prior :math:`\theta_i \sim \mathcal N(\mu_i, \sigma_i^2)`. The
output-error residual (:mod:`diffship.fit.kernel`) then gets one more row per prior,

.. math::
    e^{\text{prior}}_i = \frac{\theta_i(z) - \mu_i}{\sigma_i},

so Levenberg–Marquardt minimises the negative log posterior and returns the MAP estimate. With
the data rows normalised by their noise level, the posterior covariance is

.. math::
    \Sigma_{\text{post}} = \big(J_d^\top J_d/\hat\sigma^2 + J_p^\top J_p\big)^{-1},

and the share of the information on parameter *i* that came from the data is
:math:`1 - \Sigma_{\text{post},ii}/\sigma_i^2` (0: the prior alone; 1: the data alone).

Where to get a prior:

* the model's **reference set** (:func:`reference_priors`): a model class that declares
  ``REFERENCE = "..."`` has published or standard defaults (MMG: the KVLCC2 L7 model of
  Yasukawa & Yoshimura 2015; Fossen 3-DOF: the seed-002 USV standard model; Fossen 6-DOF:
  BlueROV2 Heavy). Every free parameter gets the reference value as mean and a standard
  deviation of ``rel_sd·|value|`` (at least ``rel_sd·scale``); a zero reference value (not in
  the set) gives no prior. These priors are used by default
  only when the model's fixed parameters (mass, inertia, main dimensions …) *are* the reference
  vessel's: a prior from another ship would be wrong;
* the user: ``NAME=MEAN±SD`` on the command line (:func:`parse_priors`), a JSON file
  (:func:`load_priors`) or :class:`Prior` objects in Python.
"""

from __future__ import annotations

import dataclasses
import json
import math
import re
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from ..errors import ModelError
from ..models import AbstractModel
from ..params import ParamSpec

__all__ = ["Prior", "Priors", "parse_priors", "load_priors", "reference_priors", "reference_class", "default_priors",
           "prior_arrays", "prior_table", "format_priors"]


@dataclasses.dataclass(frozen=True)
class Prior:
    """Gaussian prior on one parameter (model SI units).

    Attributes:
        mean: prior mean :math:`\\mu`.
        sd: prior standard deviation :math:`\\sigma` (> 0, finite).
        source: where it comes from, for reports.
    """

    mean: float
    sd: float
    source: str = "user"

    def __post_init__(self):
        if not (math.isfinite(self.mean) and math.isfinite(self.sd) and self.sd > 0):
            raise ModelError(f"prior {self.mean}±{self.sd}: the mean must be finite and the standard "
                             "deviation a positive finite number")


@dataclasses.dataclass(frozen=True)
class Priors:
    """Priors by parameter name, and a one-line description of where they come from."""

    by_name: Mapping[str, Prior]
    source: str = "user"

    def __len__(self) -> int:
        return len(self.by_name)

    def merged(self, other: Priors | None) -> Priors:
        """These priors with ``other``'s replacing any on the same parameter."""
        if other is None or not len(other):
            return self
        if not len(self):
            return other
        return Priors({**self.by_name, **other.by_name}, f"{self.source}; {other.source}")

    def check(self, spec: ParamSpec) -> None:
        """Raise a clear error for priors on unknown parameters."""
        unknown = [n for n in self.by_name if n not in spec]
        if unknown:
            raise ModelError(f"prior on unknown parameter(s) {', '.join(unknown)}; this model has "
                             f"{', '.join(spec.names)}")

    def as_json(self) -> dict:
        return {n: {"mean": p.mean, "sd": p.sd, "source": p.source} for n, p in self.by_name.items()}


_PRIOR = re.compile(r"^\s*([A-Za-z_][A-Za-z0-9_]*)\s*=\s*([^±]+?)\s*(?:±|\+-|\+/-)\s*(.+?)\s*(%?)\s*$")


def parse_priors(items: Sequence[str] | None) -> Priors:
    """Parse ``["NAME=MEAN±SD", ...]`` (``+-`` or ``+/-`` also accepted; ``SD%`` relative to MEAN)."""
    out = {}
    for item in items or ():
        m = _PRIOR.match(item)
        if not m:
            raise ModelError(f"--prior {item!r}: expected NAME=MEAN±SD (or NAME=MEAN+-SD, SD may end in %), "
                             "e.g. --prior Nrrr=-0.05±0.02")
        name, mean, sd, pct = m.groups()
        try:
            mu, s = float(mean), float(sd)
        except ValueError:
            raise ModelError(f"--prior {item!r}: {mean!r} or {sd!r} is not a number") from None
        if pct:
            s = abs(mu) * s / 100.0
        out[name] = Prior(mu, s, "command line")
    return Priors(out, "command line") if out else Priors({}, "none")


def load_priors(path: str | Path) -> Priors:
    """Priors from a JSON file ``{"NAME": {"mean": .., "sd": ..}, ...}`` (or ``[mean, sd]`` pairs)."""
    path = Path(path)
    try:
        raw = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise ModelError(f"prior file {path}: {exc}") from None
    if isinstance(raw, dict) and "priors" in raw and isinstance(raw["priors"], dict):
        raw = raw["priors"]  # a saved fit file's priors section
    out = {}
    for name, v in raw.items():
        try:
            mean, sd = (v["mean"], v["sd"]) if isinstance(v, Mapping) else (v[0], v[1])
            out[name] = Prior(float(mean), float(sd), f"file {path.name}")
        except (KeyError, IndexError, TypeError, ValueError):
            raise ModelError(f"prior file {path}: entry {name!r} must be {{\"mean\": M, \"sd\": S}} or [M, S]") from None
    return Priors(out, f"file {path.name}")


def reference_class(model: AbstractModel) -> type:
    """The model class whose reference set applies to ``model``: its own, or for a base model with effects or
    terms (:class:`~diffship.models.effects.Augmented`) its base's. The added parameters (a current, a library
    term) have no reference value and get no prior; the base's coefficients keep theirs, so that a fit with an
    effect is regularised as the base fit is and the two are compared under the same priors."""
    m = model
    while not getattr(type(m), "REFERENCE", "") and isinstance(getattr(m, "base", None), AbstractModel):
        m = m.base
    return type(m)


def reference_priors(model: AbstractModel, spec: ParamSpec, rel_sd: float = 0.5) -> Priors:
    """Priors on every free parameter from the model class's reference values (its defaults).

    Mean = the class default; standard deviation ``rel_sd·max(|default|, scale)``. Parameters
    whose reference value is exactly zero get no prior (not in the reference set).
    """
    cls = reference_class(model)
    ref, src = cls.PARAMS, getattr(cls, "REFERENCE", None)
    if not src:
        return Priors({}, "none")
    out = {}
    for p in ref:
        # a zero reference value means "not in the reference set" (the seed-002 USV has no
        # added masses; a rudder offset belongs to a test, not to a hull): no prior
        if p.name in spec.free_names and p.value != 0.0:
            out[p.name] = Prior(p.value, rel_sd * max(abs(p.value), p.scale), f"reference: {src}")
    return Priors(out, f"reference set {src} (±{100 * rel_sd:.0f} %)")


def default_priors(model: AbstractModel, spec: ParamSpec, rel_sd: float = 0.5) -> tuple[Priors, str]:
    """The priors a fit uses when the user says nothing, and a sentence saying why.

    Reference priors apply only when every *fixed* parameter is at the reference vessel's value
    (mass, inertia, dimensions, …): otherwise the vessel is another one and its reference
    coefficients would be a wrong prior.
    """
    cls = reference_class(model)
    src = getattr(cls, "REFERENCE", None)
    if not src:
        return Priors({}, "none"), f"no reference set for model {model.name}: no priors"
    ref = {p.name: p.value for p in cls.PARAMS}
    vals = spec.values()
    other = [n for n in spec.fixed_names if n in ref
             and not math.isclose(vals[n], ref[n], rel_tol=1e-9, abs_tol=1e-12)]
    if other:
        return Priors({}, "none"), (f"priors off: fixed parameter(s) {', '.join(other[:6])} differ from the "
                                    f"reference vessel ({src}), so its coefficients are not a prior for this one")
    pri = reference_priors(model, spec, rel_sd)
    return pri, (f"priors on by default: {pri.source} on {len(pri)} free parameter(s); --no-prior turns them off")


def prior_arrays(priors: Priors | None, spec: ParamSpec) -> tuple[np.ndarray, np.ndarray]:
    """``(mean, 1/sd)`` over ``spec.free_names`` (``1/sd = 0`` where a parameter has no prior)."""
    free = spec.free_names
    mean, w = np.zeros(len(free)), np.zeros(len(free))
    if priors is not None:
        priors.check(spec)
        for i, n in enumerate(free):
            p = priors.by_name.get(n)
            if p is not None:
                mean[i], w[i] = p.mean, 1.0 / p.sd
    return mean, w


def prior_table(priors: Priors, params: Mapping[str, float], stderr: Mapping[str, float],
                free: Sequence[str]) -> dict[str, dict[str, float | str]]:
    """Per parameter with a prior: prior, posterior and the share of information from the data."""
    out: dict[str, dict[str, float | str]] = {}
    for n in free:
        p = priors.by_name.get(n)
        if p is None:
            continue
        post = float(stderr.get(n, math.nan))
        ratio = (post / p.sd) ** 2 if math.isfinite(post) else math.nan
        out[n] = {"mean": p.mean, "sd": p.sd, "source": p.source, "posterior": float(params[n]),
                  "posterior_sd": post, "variance_ratio": ratio,
                  "data_share": 1.0 - ratio if math.isfinite(ratio) else math.nan,
                  "z_from_prior": (float(params[n]) - p.mean) / p.sd}
    return out


def format_priors(result) -> str:
    """Text block for a fit's report: where the priors came from, and per parameter prior,
    posterior and the share of its information that came from the data; then the
    identifiability findings."""
    info = result.info
    lines = [f"priors: {info.get('prior_note', 'none')}"]
    table = info.get("priors") or {}
    if table:
        lines.append(f"  {'parameter':>10s} {'prior':>22s} {'posterior':>22s} {'from data':>9s}")
        for n, t in table.items():
            share = t["data_share"]
            sh = f"{100 * share:7.1f} %" if math.isfinite(share) else "      n/a"
            lines.append(f"  {n:>10s} {t['mean']:>11.4g} ± {t['sd']:<8.3g} {t['posterior']:>11.4g} ± "
                         f"{t['posterior_sd']:<8.3g} {sh}")
    ident = info.get("identifiability") or {}
    warn = ident.get("warnings") or []
    cond = ident.get("condition")
    lines.append(f"identifiability: condition number {cond if isinstance(cond, str) else f'{cond:.3g}'}"
                 + (", no warnings" if not warn else f", {len(warn)} warning(s):"))
    lines.extend(f"  ! {w}" for w in warn)
    return "\n".join(lines)
