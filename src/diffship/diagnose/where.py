r"""Where does the model miss? Error splits, residual tests, force residuals and a gap budget.

All errors here are whole-horizon simulation errors on held-out runs (as in
:func:`diffship.metrics.evaluate`), heading wrapped to (−π, π].

* **Noise floor** per channel from the measured signal itself, valid for white *and* coloured
  noise (:func:`noise_estimates`). The white-noise difference estimator (Rice 1984 / von
  Neumann) :math:`\hat\sigma^2 = \mathrm{mean}((y_{k+1} - 2y_k + y_{k-1})^2)/6` is only the
  lag-1 point of the second-difference structure function
  :math:`g(k) = \mathrm{mean}((y_{i+k} - 2y_i + y_{i-k})^2)/6`. For a smooth signal plus AR(1)
  noise of variance σ² and lag-1 correlation φ,

  .. math::
      g(k) = \sigma^2\,(6 - 8\phi^k + 2\phi^{2k})/6 + b\,k^4

  (b k⁴: the signal's second derivative, :math:`b \approx \overline{\ddot s^2}\,\Delta t^4/6`).
  White noise gives a flat g (φ = 0), filtered or coloured noise a g that rises over the noise
  correlation time to its plateau σ² — at lag 1 it reads only :math:`\sigma^2(6 - 8\phi +
  2\phi^2)/6`, far too low (on smoothed real data this made E come out in the hundreds). The
  fit (grid over φ, non-negative least squares for σ², b, relative weights) over lags up to
  ``max_lag_s`` gives σ; the coloured estimate is used when φ̂ ≥ 0.3 and it exceeds the white
  one by 20 %, else the white one; :class:`NoiseEstimate` says which.
* **Normalised error** :math:`E = \sqrt{\mathrm{mean}_c (\mathrm{RMSE}_c/\sigma_c)^2}` — 1 at the
  noise floor.
* **Phases** from the steering input ``s`` (rudder or steering force) and the yaw rate ``r``:
  *approach* before the first steering action, *transient* while the steering input moves fast
  (and 2 s after), *counter-steer* when ``s`` and ``r`` have opposite signs, *steady turn*
  otherwise with |s| large, *straight* with |s| small.
* **Regions**: quartile bins of speed U, |r|, drift angle |β| and |steering input|.
* **Whiteness**: residual ACF at lags 1..L with the 95 % band ±1.96/√N; residual–input
  cross-correlation (lags 0..L, input and input rate) with the same band (Ljung 1999 §16.6).
* **Force residuals** (inverse dynamics, 3-DOF models): :math:`\tau_{res} = M\dot\nu + C\nu +
  D\nu - \tau` from smoothed measured states, per DOF.
* **Gap budget**: :math:`E^2 = E_{noise}^2 + E_{param}^2 + E_{struct}^2` (normalised units,
  :math:`E_{noise} = 1`), with the first-order approximation :math:`E_{param}^2 \approx E^2 p/N`
  (p free parameters of the base fit, N residuals) — not a propagation of the covariance
  through a validation Jacobian.
* **Gap gate** (:func:`structural_gate`): a structural gap exists when E is above what noise
  alone gives with *these* sample counts. With no structural error, :math:`E^2 = \frac1C\sum_c
  \widehat{\mathrm{MS}}_c/\hat\sigma_c^2` scatters around :math:`1 + p/N` (the base fit's p
  parameters on N residuals, as in the gap budget) because (i) the validation mean square of
  :math:`N_{v,c}` noise samples has relative variance :math:`2\kappa_c/N_{v,c}` and (ii) the
  noise floor itself is estimated: the second-difference estimator has relative variance
  :math:`(140/36)\,\kappa_c/N_{f,c}` on :math:`N_{f,c}` samples (the variance of the mean of
  :math:`(n_{k+1}-2n_k+n_{k-1})^2`, whose lag-0, 1, 2 covariances are 72, 32, 2 σ⁴), with
  :math:`\kappa_c = (1+\phi_c^2)/(1-\phi_c^2)` the AR(1) inflation of a mean of squares
  (φ = 0 for white noise; with the coloured fit the same form is an approximation, and the
  acceptance rule's validation-gain tests still guard every attribution). Averaged over C channels, :math:`\mathrm{sd}(E^2) =
  \sqrt{\sum_c v_c}/C`, and the gate is :math:`E_{gate} = \sqrt{1 + p/N + z\,\mathrm{sd}(E^2)}`
  with z = 3 (one-sided, about 0.1 % false gaps per diagnosis under a Gaussian approximation).
  On two 70-s ship zigzags at 10 Hz (ψ, r) it is 1.05; on two 40-s USV runs (six channels)
  1.04; a fixed 1.1 ignored the sample count: too strict on long data, too lax on short runs.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from typing import ClassVar

import jax
import jax.numpy as jnp
import numpy as np

from ..data import Run
from ..errors import DataError
from ..fit import FitResult
from ..metrics import Evaluation
from ..models import AbstractModel
from ..preprocess import Filter, smooth_and_derivative
from ..models.effects import is_ship3, steering_inputs
from .periodic import periodic_residual
from .words import channel_words, overshoots, where_in_words

__all__ = ["noise_floor", "noise_estimates", "PHYSICAL", "NoiseEstimate", "normalised_error", "phases", "where_analysis", "WhereAnalysis", "GapBudget",
           "gap_budget", "force_residuals", "PHASES", "structural_gate", "GapGate"]

PHASES = ("approach", "transient", "steady_turn", "counter_steer", "straight")


@dataclasses.dataclass(frozen=True)
class NoiseEstimate:
    """Noise level of one channel: ``sigma`` (used), ``method`` (which estimate), the white
    second-difference value, the fitted lag-1 correlation ``rho`` and correlation time [s]."""

    sigma: float
    method: str
    white_sigma: float
    rho: float
    corr_time_s: float
    note: str = ""


WHITE = "white (second differences)"
COLOURED = "coloured (AR(1) structure-function fit)"


def _structure(runs: Sequence[Run], c: str, angles, max_lag_s: float) -> tuple[np.ndarray, float]:
    """g(k), k = 1..K, pooled over runs, and the sample interval."""
    ys, dts = [], []
    for r in runs:
        if not r.has(c):
            continue
        y = np.asarray(r[c], dtype=float)
        ys.append(np.unwrap(y) if c in angles else y)
        dts.append(float(np.median(np.diff(np.asarray(r.time)))))
    if not ys:
        return np.zeros(1), 1.0
    dt = float(np.median(dts))
    K = int(max(1, min(round(max_lag_s / dt), min(y.size for y in ys) // 10)))
    g = []
    for k in range(1, K + 1):
        num = sum(float(np.sum((y[2 * k:] - 2 * y[k:-k] + y[:-2 * k]) ** 2)) for y in ys if y.size > 2 * k)
        cnt = sum(y.size - 2 * k for y in ys if y.size > 2 * k)
        g.append(num / max(cnt, 1) / 6.0)
    return np.asarray(g), dt


def _fit_structure(g: np.ndarray) -> tuple[float, float]:
    """(σ², φ) of g(k) = σ²(6 − 8φ^k + 2φ^2k)/6 + b k⁴, relative least squares over a φ grid."""
    from scipy.optimize import nnls

    k = np.arange(1, g.size + 1, dtype=float)
    w = 1.0 / np.maximum(g, 1e-300)
    best = (math.inf, float(g[0]), 0.0)
    for phi in np.concatenate([[0.0], np.linspace(0.05, 0.98, 48)]):
        A = np.stack([(6 - 8 * phi ** k + 2 * phi ** (2 * k)) / 6, k ** 4], axis=1) * w[:, None]
        x, res = nnls(A, g * w)
        if res < best[0]:
            best = (res, float(x[0]), float(phi))
    return best[1], best[2]


def noise_estimates(runs: Sequence[Run], channels: Sequence[str], angles=("psi",),
                    max_lag_s: float = 1.5) -> dict[str, NoiseEstimate]:
    """Per-channel noise level valid for white and coloured (AR(1)-like) noise (module docstring)."""
    out = {}
    for c in channels:
        g, dt = _structure(runs, c, angles, max_lag_s)
        white = float(max(math.sqrt(g[0]), 1e-9))
        if g.size >= 4 and np.all(g > 0):
            s2, phi = _fit_structure(g)
            col = math.sqrt(max(s2, 0.0))
        else:
            col, phi = white, 0.0
        coloured = phi >= 0.3 and col > 1.2 * white
        tau = -dt / math.log(phi) if 0 < phi < 1 else 0.0
        note = (f"noise correlated beyond the {max_lag_s:g} s fitting window (lag-1 correlation at the grid "
                "limit): sigma is a lower bound" if coloured and phi >= 0.97 else "")
        out[c] = NoiseEstimate(sigma=float(max(col if coloured else white, 1e-9)),
                               method=COLOURED if coloured else WHITE, white_sigma=white, rho=float(phi),
                               corr_time_s=float(tau), note=note)
    return out


#: ``NoiseEstimate.method`` prefix of a floor set by the sensor, not estimated (:mod:`.floors`)
PHYSICAL = "physical"


#: relative variance × N of the white second-difference variance estimator (module docstring)
SECOND_DIFF_VAR = 140.0 / 36.0


@dataclasses.dataclass(frozen=True)
class GapGate:
    """The gap gate used: ``value`` (E ≥ value: a structural gap), the null's ``sd_E2`` (sampling
    standard deviation of E² with no structural error), ``z``, the parameter term ``param_sq``
    (p/N) and how it was set (``method``)."""

    value: float
    sd_E2: float
    z: float
    param_sq: float
    method: str


def structural_gate(channels: Sequence[str], floor_runs: Sequence[Run], val_runs: Sequence[Run],
                    est: dict[str, NoiseEstimate] | None = None, param_sq: float = 0.0, z: float = 3.0) -> GapGate:
    """The gap gate from the sample counts (module docstring). ``floor_runs``: the runs the noise
    floor was estimated from (``est``; None when the noise was given: no estimation term)."""
    v = 0.0
    for c in channels:
        n_v = sum(r.n for r in val_runs if r.has(c))
        n_f = sum(r.n for r in floor_runs if r.has(c))
        e = est.get(c) if est else None
        phi = min(e.rho, 0.98) if e is not None and e.method == COLOURED else 0.0
        kappa = (1 + phi * phi) / (1 - phi * phi)
        v += 2 * kappa / max(n_v, 1)
        if est is not None and not (e is not None and e.method.startswith(PHYSICAL)):
            v += SECOND_DIFF_VAR * kappa / max(n_f, 1)
    sd = math.sqrt(v) / max(len(channels), 1)
    how = "given noise: validation sampling only" if est is None else "validation sampling and noise-floor estimation"
    return GapGate(float(math.sqrt(1.0 + param_sq + z * sd)), float(sd), z, float(param_sq),
                   f"from the sample counts ({how}), z = {z:g}")


def noise_floor(runs: Sequence[Run], channels: Sequence[str], angles=("psi",)) -> dict[str, float]:
    """Per-channel noise level σ (:func:`noise_estimates`; white or coloured, whichever holds)."""
    return {c: e.sigma for c, e in noise_estimates(runs, channels, angles).items()}


def normalised_error(ev: Evaluation, floor: dict[str, float], channels: Sequence[str], run: str | None = None) -> float:
    rm = ev.per_run[run]["rmse"] if run else ev.rmse
    vals = [(rm[c] / floor[c]) ** 2 for c in channels if c in rm]
    return float(np.sqrt(np.mean(vals))) if vals else float("nan")


def _steer(model: AbstractModel, run: Run) -> np.ndarray:
    """The steering input (rudder, nozzle, or the yaw moment for force inputs)."""
    idx = steering_inputs(model)
    return np.asarray(run[model.input_names[idx[-1]]], dtype=float)


def phases(model: AbstractModel, run: Run) -> np.ndarray:
    """Phase label per sample (strings from :data:`PHASES`)."""
    t = np.asarray(run.time, dtype=float)
    s = _steer(model, run)
    amp = max(float(np.max(np.abs(s))), 1e-12)
    ds = np.gradient(s, t)
    fast = np.abs(ds) > 0.05 * amp  # moving more than 5 % of full scale per second
    # widen transients by 2 s
    dt = float(np.median(np.diff(t)))
    w = max(1, int(round(2.0 / dt)))
    fast = np.convolve(fast.astype(float), np.ones(w), mode="full")[: t.size] > 0
    lab = np.full(t.size, "straight", dtype=object)
    big = np.abs(s - np.median(s[: max(3, t.size // 50)])) > 0.1 * amp
    first = int(np.argmax(big | fast)) if np.any(big | fast) else t.size
    r = np.asarray(run["r"], dtype=float) if run.has("r") else np.zeros_like(t)
    rthr = 0.05 * max(float(np.max(np.abs(r))), 1e-12)
    sign_s = np.sign(s)  # steering inputs are starboard-positive (positive s gives positive r)
    lab[big] = "steady_turn"
    lab[big & (np.abs(r) > rthr) & (np.sign(r) != sign_s)] = "counter_steer"
    lab[fast] = "transient"
    lab[:first] = "approach"
    return lab


def _acf(x: np.ndarray, L: int) -> np.ndarray:
    x = x - x.mean()
    c0 = float(x @ x) or 1.0
    return np.array([float(x[: x.size - k] @ x[k:]) / c0 for k in range(0, L + 1)])


def _ccf(e: np.ndarray, u: np.ndarray, L: int) -> np.ndarray:
    e = e - e.mean()
    u = u - u.mean()
    den = float(np.sqrt((e @ e) * (u @ u))) or 1.0
    return np.array([float(e[k:] @ u[: u.size - k]) / den for k in range(0, L + 1)])


@dataclasses.dataclass(frozen=True, eq=False)
class WhereAnalysis:
    """Where the base model misses on the validation runs (``to_dict()``: the JSON ``where``).

    ``per_channel``: RMSE, noise floor, ratio and share of the error per channel; ``per_run``:
    E and RMSE per run; ``per_phase``: time share, E and RMSE per manoeuvre phase;
    ``per_region``: E and bias per quartile bin of U, |r|, |β|, |steering|; ``in_words``: per
    channel (heading, rate, speed first) the error in user units and what it is, ``zigzag``: the
    overshoot angles measured and simulated per zigzag run [°] (:mod:`.words`); ``periodic``: a
    periodic residual the steering does not drive (:mod:`.periodic`); ``residual_tests``:
    ACF, CCF with the input and its rate, whiteness/independence flags; ``force_residuals``:
    inverse-dynamics RMS and mean per DOF (3-DOF models only, else None). ``residuals`` and
    ``phases`` (per run and channel / sample) feed the figures, not the JSON.
    """

    per_channel: dict
    per_run: dict
    per_phase: dict
    per_region: dict
    residual_tests: dict
    residuals: dict[str, dict[str, np.ndarray]]
    phases: dict[str, np.ndarray]
    force_residuals: dict | None = None
    in_words: tuple[dict, ...] = ()
    zigzag: dict | None = None
    periodic: dict | None = None

    @property
    def summary(self) -> str:
        """The miss in a naval architect's words (:func:`~.words.where_in_words`)."""
        return where_in_words(list(self.in_words), self.zigzag or {}, self.per_phase, self.per_region, self.periodic)

    def to_dict(self) -> dict:
        out = {"in_words": list(self.in_words), "zigzag_overshoots_deg": self.zigzag or {},
               "periodic_residual": self.periodic,
               "per_channel": self.per_channel, "per_run": self.per_run, "per_phase": self.per_phase,
               "per_region": self.per_region, "residual_tests": self.residual_tests}
        if self.force_residuals is not None:
            out["force_residuals"] = self.force_residuals
        return out


def where_analysis(model: AbstractModel, runs: Sequence[Run], ev: Evaluation, floor: dict[str, float],
                   channels: Sequence[str], max_lag_s: float = 10.0, flt: Filter = Filter()) -> WhereAnalysis:
    """Where the (base) model misses on ``runs`` given its evaluation ``ev``."""
    chans = [c for c in channels if c in ev.rmse]
    res = {}
    for run in runs:
        sim = ev.simulated[run.name]
        e = {}
        for c in chans:
            d = sim[c] - np.asarray(run[c])
            if c in model.angle_outputs:
                d = np.arctan2(np.sin(d), np.cos(d))
            e[c] = d
        res[run.name] = e
    # -- per channel
    per_channel = {c: {"rmse": ev.rmse[c], "noise_floor": floor[c], "ratio": ev.rmse[c] / floor[c]} for c in chans}
    tot = sum((ev.rmse[c] / floor[c]) ** 2 for c in chans) or 1.0
    for c in chans:
        per_channel[c]["share"] = (ev.rmse[c] / floor[c]) ** 2 / tot
    # -- per run
    per_run = {r.name: {"E": normalised_error(ev, floor, chans, r.name),
                        "rmse": {c: ev.per_run[r.name]["rmse"][c] for c in chans}} for r in runs}
    # -- per phase
    acc = {p: {c: [] for c in chans} for p in PHASES}
    labels = {}
    for run in runs:
        lab = phases(model, run)
        labels[run.name] = lab
        for p in PHASES:
            m = lab == p
            for c in chans:
                acc[p][c].append(res[run.name][c][m])
    per_phase = {}
    n_all = sum(r.n for r in runs)
    for p in PHASES:
        n = int(sum(a.size for a in acc[p][chans[0]]))
        if n == 0:
            continue
        z = [np.mean(np.concatenate(acc[p][c]) ** 2) / floor[c] ** 2 for c in chans]
        per_phase[p] = {"fraction_of_time": n / n_all, "E": float(np.sqrt(np.mean(z))),
                        "rmse": {c: float(np.sqrt(np.mean(np.concatenate(acc[p][c]) ** 2))) for c in chans}}
    # -- per region (quartile bins)
    feats = {}
    for run in runs:
        f = {}
        if run.has("u"):
            u = np.asarray(run["u"])
            v = np.asarray(run["v"]) if run.has("v") else 0 * u
            f["U"] = np.hypot(u, v)
            f["abs_beta"] = np.abs(np.arctan2(-v, np.maximum(np.abs(u), 1e-6)))
        if run.has("r"):
            f["abs_r"] = np.abs(np.asarray(run["r"]))
        f["abs_steer"] = np.abs(_steer(model, run))
        feats[run.name] = f
    per_region = {}
    for k in sorted(set.intersection(*[set(f) for f in feats.values()])):
        x = np.concatenate([feats[r.name][k] for r in runs])
        edges = np.unique(np.quantile(x, [0, 0.25, 0.5, 0.75, 1.0]))
        if edges.size < 2:
            continue
        idx = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, edges.size - 2)
        bins = []
        for b in range(edges.size - 1):
            m = idx == b
            if not np.any(m):
                continue
            z = [np.mean(np.concatenate([res[r.name][c] for r in runs])[m] ** 2) / floor[c] ** 2 for c in chans]
            mean_bias = {c: float(np.mean(np.concatenate([res[r.name][c] for r in runs])[m])) for c in chans}
            bins.append({"low": float(edges[b]), "high": float(edges[b + 1]), "n": int(m.sum()),
                         "E": float(np.sqrt(np.mean(z))), "bias": mean_bias})
        per_region[k] = bins
    # -- whiteness and cross-correlation
    corr = {}
    for c in chans:
        acfs, ccfs, ccfd = [], [], []
        for run in runs:
            dt = float(np.median(np.diff(run.time)))
            L = int(min(max_lag_s / dt, run.n // 4))
            e = res[run.name][c]
            s = _steer(model, run)
            acfs.append(_acf(e, L))
            ccfs.append(_ccf(e, s, L))
            ccfd.append(_ccf(e, np.gradient(s, run.time), L))
        L = min(a.size for a in acfs) - 1
        n = sum(r.n for r in runs)
        band = 1.96 / np.sqrt(n / len(runs))
        acf = np.mean([a[: L + 1] for a in acfs], axis=0)
        ccf = np.mean([a[: L + 1] for a in ccfs], axis=0)
        ccd = np.mean([a[: L + 1] for a in ccfd], axis=0)
        corr[c] = {"lag_s": float(dt), "band": float(band), "acf": acf.tolist(), "ccf_input": ccf.tolist(),
                   "ccf_input_rate": ccd.tolist(),
                   "white": bool(np.mean(np.abs(acf[1:]) > band) <= 0.1),
                   "independent_of_input": bool(np.mean(np.abs(ccf) > band) <= 0.1 and np.mean(np.abs(ccd) > band) <= 0.1),
                   "ccf_peak_lag_s": float(np.argmax(np.abs(ccd)) * dt)}
    lpp = model.param_values().get("Lpp") if "Lpp" in model.param_names else None
    words = channel_words(runs, ev.simulated, {c: ev.rmse[c] for c in chans}, floor, model.angle_outputs, lpp)
    zig = {}
    if "psi" in chans:
        for run in runs:
            m = overshoots(run.time, _steer(model, run), np.asarray(run["psi"]))
            if m:
                p = overshoots(run.time, _steer(model, run), np.asarray(ev.simulated[run.name]["psi"]))
                zig[run.name] = {"measured": [float(np.degrees(x)) for x in m], "model": [float(np.degrees(x)) for x in p]}
    return WhereAnalysis(per_channel=per_channel, per_run=per_run, per_phase=per_phase, per_region=per_region,
                         residual_tests=corr, residuals=res, phases=labels,
                         force_residuals=force_residuals(model, runs, flt) if is_ship3(model) else None,
                         in_words=tuple(words), zigzag=zig,
                         periodic=periodic_residual(runs, res, {r.name: _steer(model, r) for r in runs}, chans))


def force_residuals(model: AbstractModel, runs: Sequence[Run], flt: Filter = Filter()) -> dict:
    r"""RMS of :math:`M\dot\nu + C\nu + D\nu - \tau` per DOF [N, N, N·m] from smoothed data.

    Where a channel cannot be smoothed with ``flt`` (non-uniform sampling, too few samples) the
    raw signal and its finite-difference derivative are used, and ``"notes"`` says so per run and
    channel: never a silent fallback.
    """
    if not hasattr(model, "coriolis_vector"):
        return {}
    acc = {"X": [], "Y": [], "N": []}
    notes: list[str] = []
    for run in runs:
        if not run.has("u", "v", "r") or not all(run.has(n) for n in model.input_names):
            continue
        t = np.asarray(run.time)
        nu, nud = [], []
        for c in ("u", "v", "r"):
            try:
                ys, yd = smooth_and_derivative(t, np.asarray(run[c]), flt, f"run {run.name}, column {c}")
            except DataError as exc:
                notes.append(f"{exc}: used the unsmoothed signal and central differences instead")
                ys, yd = np.asarray(run[c]), np.gradient(np.asarray(run[c]), t)
            nu.append(ys)
            nud.append(yd)
        nu, nud = np.stack(nu, 1), np.stack(nud, 1)
        us = np.stack([np.asarray(run[n]) for n in model.input_names], 1)

        def one(nu_k, nud_k, u_k):
            m = model
            return m.mass_matrix() @ nud_k + m.coriolis_vector(nu_k) + m.damping_vector(nu_k) - m.forces(u_k, nu_k)

        f = np.asarray(jax.vmap(one)(jnp.asarray(nu), jnp.asarray(nud), jnp.asarray(us)))
        for j, k in enumerate(("X", "Y", "N")):
            acc[k].append(f[:, j])
    out: dict = {k: {"rms": float(np.sqrt(np.mean(np.concatenate(v) ** 2))), "mean": float(np.mean(np.concatenate(v)))}
                 for k, v in acc.items() if v}
    if notes:
        out["notes"] = notes
    return out


@dataclasses.dataclass(frozen=True)
class GapBudget:
    """:math:`E^2 = E_{noise}^2 + E_{param}^2 + E_{struct}^2` on the validation runs
    (normalised units, noise floor = 1), and each part's share of :math:`E^2`."""

    E_total: float
    E_noise: float
    E_param: float
    E_struct: float
    share_noise: float
    share_param: float
    share_struct: float

    NOTE: ClassVar[str] = ("E is the validation RMS error per channel divided by the channel noise floor, averaged in "
            "quadrature; E_param is a first-order approximation E*sqrt(p/N) (p free parameters, N residuals), "
            "not a propagation of the covariance through a validation Jacobian")

    def to_dict(self) -> dict:
        return {**dataclasses.asdict(self), "note": self.NOTE}


def gap_budget(fit: FitResult, E: float) -> GapBudget:
    """Split the validation error ``E`` of the base fit ``fit`` (see the module docstring)."""
    # with p parameters fitted to N residuals the prediction variance from parameter uncertainty
    # is about p/N of the residual variance (no validation Jacobian is formed)
    n_p = len(fit.free)
    n = max(int(fit.info.get("n_residuals", 1)), 1)
    noise_sq = 1.0
    param_sq = E * E * n_p / n
    struct_sq = max(E * E - noise_sq - param_sq, 0.0)
    tot = max(E * E, 1e-300)
    return GapBudget(E_total=float(E), E_noise=1.0, E_param=float(math.sqrt(param_sq)),
                     E_struct=float(math.sqrt(struct_sq)), share_noise=float(min(noise_sq / tot, 1.0)),
                     share_param=float(param_sq / tot), share_struct=float(struct_sq / tot))
