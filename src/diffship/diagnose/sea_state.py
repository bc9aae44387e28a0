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

**A screen first.** Periodic training residuals also come from a missing deterministic term (an autopilot's own
oscillation about a missing damping term shows a line), and the full prediction-error fit then costs minutes to say
"none" (measured: a 3-DOF USV missing a sway–yaw damping term, four 240-s runs, 272 s, its damping on the bound).
So the check first makes a :data:`SCREEN_STEPS`-step fit from the base fit's values alone and computes the same
shares; where the largest is under half of :data:`SHARE_MIN` it stops there and says so. Measured, the screen's
share of the held-out yaw rate against the full fit's: in narrow-band waves 0.79 (full fit 0.41; 3-DOF USV), 0.28
(0.32; the USV's second seed) and 0.82 (0.59; Nomoto); on the USV missing its damping term 0.016, where the full fit
found none (its damping on the bound) — the whole check 20 s instead of 272 s.

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
from ..fit import FitResult, fit
from ..fit.ahead import ahead
from ..fit.disturbance import CLIP
from ..fit.output_error import OutputErrorOptions
from ..fit.prediction_error import PredictionError, PredictionErrorOptions, fit_prediction_error

__all__ = ["SeaState", "sea_state", "SHARE_MIN", "SCREEN_STEPS", "NarrowBandCheck"]

#: Smallest share of the held-out one-sample prediction error the sea state must account for.
SHARE_MIN = 0.10
#: Levenberg–Marquardt steps of the screen (module docstring); a screen's share under ``SHARE_MIN / 2`` ends the check.
SCREEN_STEPS = 20


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


@dataclasses.dataclass(frozen=True)
class NarrowBandCheck(PredictionError):
    """Prediction error with a ``wave`` disturbance that only has to say whether the wave is narrow-band.

    Its solves end once the wave's damping reaches the upper bound of its clip (:data:`~diffship.fit.disturbance.CLIP`;
    :mod:`diffship.fit.batched`, item 7). Beyond the clip the damping's Jacobian column is zero, so no later step
    brings it back: a solve that reaches the bound ends on it, and a fit whose every solve ends there is broad,
    whatever its further steps would do to the other unknowns (measured: a 3-DOF USV with a deterministic wave
    force passed the bound by step 21 of 200, whose last 180 steps lowered the cost by 0.2 % and changed nothing of
    the verdict). So the check's answer is the full fit's:

    * every solve (each start, and the disturbance-dominated noise start where it runs) on the bound: the fit ends
      there, broad (its other values are those of the step the bound was reached, ``info["ended_at_bound"]``);
    * none on it: the rule never fired, the solves are the full fit's;
    * some on it, some not: the ones that ended early are not comparable by cost, and the fit is made again without
      the rule.
    """

    def _solves(self, problem, z0s, say, label="prediction error", data=None):
        outs = super()._solves(problem, z0s, say, label, data)
        if "stop_above" in problem.state["lm"]:
            problem.state["broad"] += [bool(o_[0][-1] >= CLIP["wave_damping"][1]) for o_ in outs]
        return outs

    def first_solves(self, problem, zs, say):
        st_, k = problem.state, problem.state["kernel"]
        lm, st_["broad"] = st_["lm"], []
        if k.disturbance == "wave" and k.n_noise:  # the damping: the last unknown; held at its start in the held
            # solve (so the rule never fires there, and the held and the free solve keep one compiled program)
            st_["lm"] = {**lm, "stop_above": ((len(zs[0]) - 1, CLIP["wave_damping"][1]),)}
        outs = super().first_solves(problem, zs, say)
        st_["lm"] = lm
        if any(st_["broad"]) and not all(st_["broad"]):
            say("sea state: some solves ended with the wave's damping on its bound and some did not: solving again "
                "to the end")
            st_["broad"] = []
            return super().first_solves(problem, zs, say)
        st_["ended_at_bound"] = bool(st_["broad"]) and all(st_["broad"])
        return outs

    def finish(self, problem, z, steps, say):
        solved, ended = super().finish(problem, z, steps, say), bool(problem.state.get("ended_at_bound"))
        note = ("every solve ended once the wave's damping reached the bound of its clip (a bound it cannot leave): "
                "a broad disturbance; the other values are those of that step, not converged")
        return dataclasses.replace(solved, info={**solved.info, "ended_at_bound": ended},
                                   messages=tuple(solved.messages) + ((note,) if ended else ()))


def _pe_fit(base_fit: FitResult, train: Sequence[Run], channels: Sequence[str], say, n_starts: int,
            max_steps: int | None = None) -> FitResult:
    """Prediction error with the ``wave`` disturbance from the base fit's values (and, with ``n_starts`` 2, the
    model's own: a base fit biased by the sea state is a poor start); the full fit (``max_steps`` ``None``) as a
    :class:`NarrowBandCheck`."""
    model = base_fit.model
    spec = model.spec().only_free(base_fit.free) if base_fit.free else model.spec()
    oe = OutputErrorOptions(integrator=base_fit.integrator, **({} if max_steps is None else {"max_steps": max_steps}))
    starts = {"the base fit's values": {n: base_fit.params[n] for n in base_fit.free}}
    noise = PredictionErrorOptions(disturbance="wave")
    if max_steps is None:
        return fit(model, train, NarrowBandCheck(oe=oe, noise=noise), spec=spec, starts=starts, n_starts=n_starts,
                   channels=tuple(channels), progress=say, throw=False)
    return fit_prediction_error(model, train, spec=spec, channels=tuple(channels), options=oe, starts=starts,
                                n_starts=n_starts, noise=noise, progress=say, throw=False)


def _shares(pe: FitResult, runs: Sequence[Run]) -> dict[str, float]:
    with_w, without = ahead(pe, runs, None, True), ahead(pe, runs, None, False)
    return {c: 1.0 - with_w.rmse[c] ** 2 / without.rmse[c] ** 2 for c in with_w.channels if without.rmse[c] > 0}


def sea_state(base_fit: FitResult, train: Sequence[Run], val: Sequence[Run], channels: Sequence[str],
              say: Callable[[str], None] = lambda s: None) -> SeaState:
    """The sea-state check of the base fit (module docstring): the screen, then, unless it rules a sea state out,
    the full prediction-error fit."""
    t0 = time.perf_counter()
    runs = list(val) or list(train)
    say(f"sea state: screening with a {SCREEN_STEPS}-step prediction-error fit with a narrow-band wave disturbance...")
    pe = _pe_fit(base_fit, train, channels, say, 1, SCREEN_STEPS)
    share = _shares(pe, runs) if math.isfinite(pe.cost) else {}
    share = share if all(math.isfinite(v) for v in share.values()) else {}  # no verdict: the full fit decides
    if share:
        say("sea state: the screen's share of the one-sample prediction error: "
            + ", ".join(f"{c} {100 * v:.1f} %" for c, v in share.items()))
    if share and max(share.values()) < 0.5 * SHARE_MIN:
        best = max(share, key=share.get)
        why = (f"a {SCREEN_STEPS}-step prediction-error screen: the wave accounts for {100 * share[best]:.1f} % of the "
               f"{'held-out ' if val else ''}one-sample prediction error in {best}, under half of "
               f"{100 * SHARE_MIN:.0f} %; the full fit was not made")
        info = pe.info
        return SeaState(False, float(info.get("wave_period", math.nan)), float(info.get("wave_damping", math.nan)),
                        dict(info.get("process_sd", {})), share, {}, why, time.perf_counter() - t0, pe)
    say("sea state: fitting the base model by prediction error with a narrow-band wave disturbance...")
    pe = _pe_fit(base_fit, train, channels, say, 2)
    if not pe.usable:
        return SeaState(False, math.nan, math.nan, {}, {}, {},
                        f"the prediction-error fit did not converge: {pe.status}", time.perf_counter() - t0, pe)
    share = _shares(pe, runs)
    period, damping = float(pe.info["wave_period"]), float(pe.info["wave_damping"])
    broad = math.log(damping / PredictionErrorOptions().wave_damping) >= CLIP["wave_damping"][1] - 1e-6
    best = max(share.values()) if share else 0.0
    found = best >= SHARE_MIN and not broad
    why = ("its damping is on its bound: a broad disturbance, not a wave"
           + (" (every solve reached the bound and ended there)" if pe.info.get("ended_at_bound") else "") if broad else
           f"it accounts for {100 * best:.1f} % of the {'held-out ' if val else ''}one-sample prediction error, "
           f"under {100 * SHARE_MIN:.0f} %")
    K_T = {n: (float(pe.params[n]), float(pe.stderr.get(n, math.nan))) for n in pe.free}
    return SeaState(found, period, damping, dict(pe.info["process_sd"]), share, K_T, "" if found else why,
                    time.perf_counter() - t0, pe)
