r"""A sea state, not a missing term: the stochastic disturbance that the model can filter but not predict.

The deterministic candidates of the library (:mod:`diffship.models.effects`) are judged by free simulation of the
held-out runs: an effect the model lacks comes back the same way on every run. Waves with a random phase per run do
not: a sinusoid of fixed phase cannot carry over from one run to another (``benchmarks/results/wave_family.md``),
and under an autopilot the rudder answers the waves, so the periodic-residual test sees the wave's line in the
steering too and gives the wave candidate no start. A sea state is judged by what can honestly be done with it:
**prediction from the Kalman filter's state** (:mod:`diffship.fit.ahead`).

The check fits the base model by prediction error with a narrow-band ``wave`` disturbance on the training runs
(:mod:`diffship.fit.disturbance`; the base fit's values as the start), then on the held-out runs predicts every
sample from the one before with the disturbance's own dynamics and without them (the same filtered state, the
disturbance set to zero). Its **share** per channel is the part of the one-sample prediction error that the sea
state accounts for,

.. math:: s_c = 1 - \frac{\mathrm{MSE}_c(\text{with})}{\mathrm{MSE}_c(\text{without})},

and a sea state is **found** when the largest share is at least :data:`SHARE_MIN` (10 %) and the fitted wave
is narrow-band (its damping not on its bound: a broad disturbance at the bound is no wave). The verdict line
then says "a sea state the model cannot predict, only filter", with its period, damping and intensity — beside,
not instead of, the deterministic verdict.

It runs when the base fit's training residuals have a periodic line the steering does not drive (:mod:`.periodic`)
or, with the loop closed (:mod:`diffship.fit.feedback`), one the steering shares that repeats at least ten times a
run (a zigzag's own period, set by its rudder, does not), or always with ``DiagnoseOptions(sea_state="always")``.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable, Sequence

from ..data import Run
from ..fit import FitResult
from ..fit.ahead import ahead
from ..fit.disturbance import CLIP
from ..fit.output_error import OutputErrorOptions
from ..fit.prediction_error import PredictionErrorOptions, fit_prediction_error

__all__ = ["SeaState", "sea_state", "SHARE_MIN"]

#: Smallest share of the held-out one-sample prediction error the sea state must account for.
SHARE_MIN = 0.10


@dataclasses.dataclass(frozen=True)
class SeaState:
    """The sea-state check (module docstring)."""

    found: bool
    period_s: float
    damping: float
    intensity: dict[str, float]
    share: dict[str, float]
    K_T: dict[str, tuple[float, float]]
    why: str
    seconds: float
    fit: FitResult | None = dataclasses.field(default=None, repr=False, compare=False)

    def line(self, gap_unexplained: bool = False) -> str:
        """The verdict line (``gap_unexplained``: no deterministic effect was attributed)."""
        best = max(self.share, key=self.share.get) if self.share else "-"
        if self.found:
            return (f"Sea state: a sea state the model cannot predict, only filter — a narrow-band disturbance at "
                    f"{self.period_s:.3g} s (relative damping {self.damping:.2g}; sd on the rate of "
                    + ", ".join(f"{k} {v:.3g}" for k, v in self.intensity.items())
                    + f" per s) accounts for {100 * self.share[best]:.0f} % of the held-out one-sample prediction "
                    f"error in {best}" + ("; the gap above is what free simulation cannot do in a sea state, not a "
                                          "missing term" if gap_unexplained else "")
                    + "; prediction error with --disturbance wave estimates the dynamics with it.")
        return f"Sea state: none found ({self.why})."

    def compare(self, params: dict[str, float], stderr: dict[str, float]) -> list[dict]:
        r"""The check's prediction-error estimates beside the base fit's (output error) for every parameter both
        have: ``{"name", "output_error", "se_output_error", "prediction_error", "se_prediction_error", "z"}`` with
        :math:`z = |\hat\theta_{PE} - \hat\theta_{OE}| / \sqrt{s_{PE}^2 + s_{OE}^2}`. Under a closed loop in a sea
        state the output-error estimates are biased (the input answers the disturbance) and the prediction-error ones
        are not: a large ``z`` says which parameters the bias moved. Empty where no sea state was found."""
        out = []
        if not self.found:
            return out
        for n, (v, s) in self.K_T.items():
            if n not in params:
                continue
            so = float(stderr.get(n, math.nan))
            comb = math.hypot(s, so) if math.isfinite(s) and math.isfinite(so) else math.nan
            out.append({"name": n, "output_error": float(params[n]), "se_output_error": so, "prediction_error": v,
                        "se_prediction_error": s, "z": abs(v - float(params[n])) / comb if comb > 0 else math.nan})
        return out

    def to_dict(self) -> dict:
        d = {f.name: getattr(self, f.name) for f in dataclasses.fields(self) if f.name != "fit"}
        return {**d, "K_T": {k: list(v) for k, v in self.K_T.items()}, "line": self.line(),
                "share_definition": "1 − MSE(one-sample prediction with the disturbance) / MSE(without), held-out "
                "runs", "share_min": SHARE_MIN}


def sea_state(base_fit: FitResult, train: Sequence[Run], val: Sequence[Run], channels: Sequence[str],
              say: Callable[[str], None] = lambda s: None) -> SeaState:
    """The sea-state check of the base fit (module docstring)."""
    t0 = time.perf_counter()
    model = base_fit.model
    spec = model.spec().only_free(base_fit.free) if base_fit.free else model.spec()
    say("sea state: fitting the base model by prediction error with a narrow-band wave disturbance...")
    pe = fit_prediction_error(model, train, spec=spec, channels=tuple(channels),
                              options=OutputErrorOptions(integrator=base_fit.integrator),
                              starts={"the base fit's values": {n: base_fit.params[n] for n in base_fit.free}},
                              n_starts=2,  # and the model's own values: a base fit biased by the sea state is a poor start
                              noise=PredictionErrorOptions(disturbance="wave"), progress=say, throw=False)
    if not pe.usable:
        return SeaState(False, math.nan, math.nan, {}, {}, {}, f"the prediction-error fit did not converge: {pe.status}",
                        time.perf_counter() - t0, pe)
    runs = list(val) or list(train)
    with_w, without = ahead(pe, runs, None, True), ahead(pe, runs, None, False)
    share = {c: 1.0 - with_w.rmse[c] ** 2 / without.rmse[c] ** 2 for c in with_w.channels if without.rmse[c] > 0}
    period, damping = float(pe.info["wave_period"]), float(pe.info["wave_damping"])
    broad = math.log(damping / PredictionErrorOptions().wave_damping) >= CLIP["wave_damping"][1] - 1e-6
    best = max(share.values()) if share else 0.0
    found = best >= SHARE_MIN and not broad
    why = ("its damping is on its bound: a broad disturbance, not a wave" if broad else
           f"it accounts for {100 * best:.1f} % of the {'held-out ' if val else ''}one-sample prediction error, "
           f"under {100 * SHARE_MIN:.0f} %")
    K_T = {n: (float(pe.params[n]), float(pe.stderr.get(n, math.nan))) for n in pe.free}
    return SeaState(found, period, damping, dict(pe.info["process_sd"]), share, K_T, "" if found else why,
                    time.perf_counter() - t0, pe)
