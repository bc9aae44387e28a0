r"""Froude scaling between a ship model and the full-scale ship, and scale-aware helm rates.

With the length ratio :math:`\lambda = L_\text{full}/L_\text{model}` and equal Froude numbers
:math:`U/\sqrt{gL}` (and equal gravity), geometric similarity gives

=====================  ====================================  ==========================
quantity               full scale = model ×                  examples
=====================  ====================================  ==========================
length, position       :math:`\lambda`                       ``x0, y0``, diameters
time                   :math:`\sqrt\lambda`                  ``time``, time to check yaw
speed                  :math:`\sqrt\lambda`                  ``u, v``
angular rate           :math:`1/\sqrt\lambda`                ``r``, helm rate
propeller rate         :math:`1/\sqrt\lambda`                ``n`` [rev/s]
angle                  1                                     ``psi, delta``, overshoots
mass, force            :math:`\lambda^3\,\rho_s/\rho_m`      ``m``, ``tau_x``
moment                 :math:`\lambda^4\,\rho_s/\rho_m`      ``tau_z``
=====================  ====================================  ==========================

(Reynolds-number effects — the model's relatively larger friction — are not scaled: a
Froude-scaled prediction is what the model test says about the ship, no more.)

**Helm rate.** IMO's minimum steering-gear rate is 35° one side to 30° the other in 28 s,
:data:`IMO_HELM_RATE_DEG_S` ≈ 2.32°/s at full scale; a model at scale λ must turn its rudder
:math:`\sqrt\lambda` times faster (KVLCC2 at λ = 45.714: 15.7°/s; HSVA used 15.8°/s).
:func:`helm_rate` never silently gives a full-scale rate to a model-scale ship.

Reference: ITTC Recommended Procedures 7.5-02-06-01 (free-running model tests), and
IMO MSC.137(76) / MSC/Circ.1053.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from .errors import ModelError

__all__ = ["FULL_SCALE_MIN_LENGTH_M", "IMO_HELM_RATE_DEG_S", "FroudeScale", "helm_rate", "model_length"]

#: IMO minimum helm rate at full scale: 65° in 28 s [°/s].
IMO_HELM_RATE_DEG_S = 65.0 / 28.0
#: A model whose length is below this is taken to be model scale (no full-scale default helm rate) [m].
FULL_SCALE_MIN_LENGTH_M = 20.0

#: How each channel scales from model to full scale (power of λ; ``"force"``: λ³ρs/ρm).
_CHANNEL_POWER = {"time": 0.5, "x0": 1.0, "y0": 1.0, "z0": 1.0, "u": 0.5, "v": 0.5, "w": 0.5, "r": -0.5, "p": -0.5,
                  "q": -0.5, "n": -0.5, "psi": 0.0, "delta": 0.0, "phi": 0.0, "theta": 0.0, "delta_n": 0.0}


@dataclasses.dataclass(frozen=True)
class FroudeScale:
    """Froude scaling by the length ratio ``lam`` = L_full / L_model (> 0).

    ``rho_model``, ``rho_full``: water densities [kg/m³] (fresh-water tank, sea water) for
    masses, forces and moments.
    """

    lam: float
    rho_model: float = 1000.0
    rho_full: float = 1025.0

    def __post_init__(self):
        if not (isinstance(self.lam, (int, float)) and math.isfinite(self.lam) and self.lam > 0):
            raise ModelError(f"Froude scale: the length ratio λ must be a positive number, got {self.lam!r}")

    @property
    def sqrt(self) -> float:
        return math.sqrt(self.lam)

    def length(self, x):
        """Model length [m] → full-scale length [m]."""
        return x * self.lam

    def time(self, t):
        """Model time [s] → full-scale time [s]."""
        return t * self.sqrt

    def speed(self, u):
        """Model speed [m/s] → full-scale speed [m/s]."""
        return u * self.sqrt

    def rate(self, r):
        """Model angular rate (yaw rate, helm rate, propeller rev/s) → full scale."""
        return r / self.sqrt

    def force(self, f):
        """Model force [N] (or mass [kg]) → full scale."""
        return f * self.lam**3 * self.rho_full / self.rho_model

    def moment(self, m):
        """Model moment [N m] → full scale."""
        return m * self.lam**4 * self.rho_full / self.rho_model

    def channel(self, name: str, values):
        """A run channel or time from model to full scale (angles unchanged); unknown names raise."""
        if name in ("tau_x", "tau_y"):
            return self.force(values)
        if name == "tau_z":
            return self.moment(values)
        if name not in _CHANNEL_POWER:
            raise ModelError(f"Froude scale: no scaling rule for channel '{name}' (known: "
                             f"{', '.join(sorted(_CHANNEL_POWER))}, tau_x, tau_y, tau_z)")
        return np.asarray(values, dtype=np.float64) * self.lam ** _CHANNEL_POWER[name]

    def channels(self, time, channels: dict[str, Any]) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """Full-scale time and channels; channels without a rule are left out."""
        out = {c: self.channel(c, v) for c, v in channels.items() if c in _CHANNEL_POWER or c.startswith("tau_")}
        return self.channel("time", time), out


def model_length(model) -> float | None:
    """The model's length [m] when it has one (``L`` field), else ``None``."""
    L = getattr(model, "L", None)
    try:
        return float(L) if L is not None else None
    except (TypeError, ValueError):
        return None


def helm_rate(model=None, *, rudder_rate_deg_s: float | None = None, scale: float | None = None,
              length: float | None = None) -> tuple[float, str]:
    """The steering-gear rate [°/s] for a simulated manoeuvre, and where it comes from.

    * ``rudder_rate_deg_s`` given: used as is;
    * ``scale`` (λ) given: IMO's 2.32°/s Froude-scaled to the model, :math:`2.32\\sqrt\\lambda`;
    * a model at least :data:`FULL_SCALE_MIN_LENGTH_M` long: 2.32°/s (full scale);
    * a shorter model: :class:`~diffship.errors.ModelError` — a model-scale ship needs its own rate;
    * a model without a length (Nomoto, ...): 2.32°/s, said in the returned text.

    ``length`` [m] stands in for the model's own length (e.g. a Nomoto model of a known ship).
    """
    if rudder_rate_deg_s is not None:
        if not rudder_rate_deg_s > 0:
            raise ModelError(f"helm rate must be positive, got {rudder_rate_deg_s!r} °/s")
        return float(rudder_rate_deg_s), "given"
    if scale is not None:
        s = FroudeScale(float(scale))
        return IMO_HELM_RATE_DEG_S * s.sqrt, f"IMO 2.32°/s at full scale × √λ (λ = {scale:g})"
    L = length if length is not None else model_length(model)
    if L is None:
        return IMO_HELM_RATE_DEG_S, "IMO full-scale 2.32°/s (the model has no length; give a rate or a scale)"
    if L >= FULL_SCALE_MIN_LENGTH_M:
        return IMO_HELM_RATE_DEG_S, f"IMO full-scale 2.32°/s (L = {L:g} m)"
    name = getattr(model, "name", "model")
    raise ModelError(
        f"{name} is L = {L:g} m long (model scale): give the helm rate (rudder_rate_deg_s=..., CLI --helm-rate) or "
        f"the scale λ (scale=..., CLI --scale), which gives IMO's 2.32°/s × √λ; the full-scale 2.32°/s would "
        "make the model's rudder √λ times too slow")
