r"""The one initial-state rule: every simulated run starts from a state estimated within its sensor noise.

A whole-horizon simulation must start somewhere, and every number diffship reports depends on where.
The logged first sample is a measurement like any other,

.. math::
    y_s(t_0) = x_{0,s} + v_s,\qquad v_s \sim N(0, \sigma_s^2),

so the initial state is an unknown of its run with that measurement as a Gaussian prior row
:math:`(x_{0,s} - y_s(t_0))/\sigma_s`, beside the run's output errors weighted by the channel scales
:math:`w_c` of the fit:

.. math::
    \hat x_0 = \arg\min_{x_0}\ \tfrac12\sum_{k,c}\Big(\frac{\hat y_c(t_k; x_0) - y_{kc}}{w_c}\Big)^2
    + \tfrac12\sum_{s}\Big(\frac{x_{0,s} - y_s(t_0)}{\sigma_s}\Big)^2 .

* **Measured states** (a state that is a fitted channel) carry that prior with :math:`\sigma_s` the
  channel's sensor noise, estimated from the data (:func:`channel_noise`). Taking the noisy sample as
  exact biases every coefficient (a heading offset never decays: on independent USV runs the yaw
  damping moved 16 standard errors), and leaving the state free lets it soak up model error.
* **States no channel measures** that are the rate of a fitted channel (Nomoto 2's internal rate, the yaw
  rate of a heading-only fit) are held loosely, within the spread that rate shows over the runs, around the
  data's filtered value: free to follow the data, but not to take values the runs never show in order to hide a
  model's error (an equation-error Nomoto 2 estimate judged from a free internal rate scored 4° instead of 70°
  on the SSPA zigzag). Other states no channel measures are free.
* **Other states** (positions that are not fitted, actuator and effect states) keep the data's value
  (:func:`diffship.simulate.initial_state`).

The balance is statistical, not a tuning: with the fit's channel scales (the residual RMS times the
square root of the residuals' correlation time, :func:`diffship.fit.weights.correlation_time`), a
correct model with white noise lets the whole run determine :math:`x_0` to
:math:`\sigma/\sqrt{N}` (the true model scores at the noise), while a model whose residuals are a
slow drift has few effective samples and cannot buy its start away from the log.

The same rule serves the fit (jointly with the parameters: the prior rows of
:class:`diffship.fit.kernel.KernelData`), the metrics of training and held-out runs (with the
parameters held: :func:`estimate_starts`), the diagnosis and discovery refits and the
cross-manoeuvre validation of ``predict``. References: Ljung, *System Identification* (1999),
§7.1 and §10.3 (initial conditions in the prediction-error criterion); MATLAB's ``compare`` and
``nlgreyest`` estimate them by default.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Bool, Float

from .compiled import compiled
from .data import Run
from .integrators import AbstractIntegrator, Diffrax
from .models import AbstractModel
from .preprocess import Filter, smooth_and_derivative
from .simulate import initial_state, model_inputs, simulate, simulate_run

__all__ = ["NOISE_FLOOR_SHARE", "StartPrior", "channel_noise", "noise_floor", "pooled_noise_floor", "rate_channel",
           "start_prior", "estimate_starts", "start_request", "estimated_states", "state_scales"]

#: The sensor-noise estimate of a channel is at least this share of its spread (noise-free data:
#: the start is then pinned to the measured value, as it should be).
NOISE_FLOOR_SHARE = 1e-3


def noise_floor(y: np.ndarray) -> float:
    r"""White-noise standard deviation of one sampled channel from its second differences, robustly:
    :math:`\hat\sigma = 1.4826\,\mathrm{MAD}(\Delta^2 y)/\sqrt6` (a smooth signal's second differences
    are small; corners and manoeuvres are outliers the median ignores)."""
    y = np.asarray(y, dtype=np.float64)
    y = y[np.isfinite(y)]
    if y.size < 5:
        return 0.0
    d2 = np.diff(y, 2)
    return float(1.4826 * np.median(np.abs(d2 - np.median(d2))) / math.sqrt(6.0))


def pooled_noise_floor(series: Sequence[np.ndarray]) -> float:
    """One channel's sensor noise pooled over runs: :func:`noise_floor` of each run's samples, root mean square
    over the runs weighted by their lengths."""
    var, n = 0.0, 0
    for y in series:
        y = np.asarray(y, dtype=np.float64)
        var += noise_floor(y) ** 2 * y.size
        n += y.size
    return math.sqrt(var / max(n, 1))


def channel_noise(ys: Float[np.ndarray, "R N C"], mask: Bool[np.ndarray, "R N"]) -> np.ndarray:
    """Sensor noise of each channel ``(C,)``, pooled over the runs (:func:`pooled_noise_floor`), at least
    :data:`NOISE_FLOOR_SHARE` of the channel's spread."""
    ys, mask = np.asarray(ys, dtype=np.float64), np.asarray(mask, dtype=bool)
    out = []
    for c in range(ys.shape[-1]):
        pooled = pooled_noise_floor([ys[i, mask[i], c] for i in range(ys.shape[0])])
        spread = float(np.std(ys[..., c][mask])) if np.any(mask) else 0.0
        out.append(max(pooled, NOISE_FLOOR_SHARE * spread, 1e-12))
    return np.asarray(out)


def estimated_states(model: AbstractModel, channels: Sequence[str]) -> tuple[str, ...]:
    """The states whose initial values are estimated for these fitted channels: the measured ones and
    the states no channel measures that shape them (``model.states_for_channels``)."""
    return tuple(model.states_for_channels(tuple(channels)))


#: An unmeasured rate whose angle is fitted moves its angle by a spread in this many seconds per scale unit.
RATE_SCALE_S = 10.0


def state_scales(model: AbstractModel, channels: Sequence[str], spread: np.ndarray, states: Sequence[str]) -> np.ndarray:
    """The unit of each estimated initial state's offset: the spread of the channel that measures it (or that
    its ``STATE_CHANNEL`` names), for the unmeasured rate of a fitted angle that angle's spread over
    :data:`RATE_SCALE_S`, else 1."""
    state_channel = getattr(model, "STATE_CHANNEL", {})
    rate_of = {w: a for a, w in (("psi", "r"), ("phi", "p"), ("theta", "q"))}

    def one(s: str) -> float:
        c = s if s in channels else state_channel.get(s)
        if c in channels:
            return float(spread[list(channels).index(c)])
        if rate_of.get(s) in channels:
            return float(spread[list(channels).index(rate_of[s])]) / RATE_SCALE_S
        return 1.0
    return np.asarray([one(s) for s in states], dtype=np.float64)


@dataclasses.dataclass(frozen=True)
class StartPrior:
    """The prior of the estimated initial states of a set of runs, as offsets from ``x0`` (the data's
    initial states) in units of ``scale``.

    Attributes:
        states: the estimated states, in order.
        scale: the unit of each state's offset ``(n_d,)``.
        mean: the measured value of each offset ``(R, n_d)`` (the raw first sample; 0 for a free state).
        weight: inverse standard deviation of each offset in ``scale`` units ``(R, n_d)`` (0: free).
        sigma: the sensor noise of each state's channel in its own unit ``(n_d,)`` (NaN: free).
    """

    states: tuple[str, ...]
    scale: np.ndarray
    mean: np.ndarray
    weight: np.ndarray
    sigma: np.ndarray

    def describe(self) -> str:
        meas = [f"{s} ±{_fmt(s, sd)}" for s, sd in zip(self.states, self.sigma) if math.isfinite(sd)]
        loose = [s for j, (s, sd) in enumerate(zip(self.states, self.sigma))
                 if not math.isfinite(sd) and np.any(self.weight[:, j] > 0)]
        free = [s for s in self.states if s not in loose and not math.isfinite(self.sigma[self.states.index(s)])]
        text = ("initial states estimated per run within their sensor noise (" + ", ".join(meas) + ")"
                if meas else "initial states estimated per run")
        text += f"; {', '.join(loose)} unmeasured, within the spread of its rate in the runs" if loose else ""
        return text + (f"; {', '.join(free)} unmeasured, free" if free else "")


def _fmt(state: str, sd: float) -> str:
    if state in ("psi", "phi", "theta"):
        return f"{math.degrees(sd):.3g}°"
    if state in ("r", "p", "q"):
        return f"{math.degrees(sd):.3g}°/s"
    return f"{sd:.3g}"


def rate_channel(model: AbstractModel, state: str) -> str | None:
    """The channel whose rate ``state`` is (``STATE_RATE_OF``; the yaw, roll or pitch rate of its angle), or None."""
    own = getattr(model, "STATE_RATE_OF", {}).get(state)
    return own or {"r": "psi", "p": "phi", "q": "theta"}.get(state)


def start_prior(model: AbstractModel, channels: Sequence[str], ys: np.ndarray, mask: np.ndarray, x0: np.ndarray,
                states: Sequence[str], scale: np.ndarray, noise: np.ndarray | None = None,
                ts: np.ndarray | None = None) -> StartPrior:
    """The :class:`StartPrior` of runs given as padded arrays (``ys (R, N, C)`` of ``channels``,
    ``mask (R, N)``, the data's initial states ``x0 (R, n_x)``, times ``ts (R, N)``): each estimated state that
    is a channel is centred on that channel's first sample with the channel's sensor noise ``noise`` (default
    :func:`channel_noise`); a state no channel measures that is the rate of a fitted channel
    (:func:`rate_channel`) is held, loosely, within the spread that rate shows over the runs (the zero-phase
    filtered derivative the data's initial state takes it from), so that it cannot take values the runs never
    show to hide a model's error; any other is free."""
    ys, x0 = np.asarray(ys, dtype=np.float64), np.asarray(x0, dtype=np.float64)
    noise = channel_noise(ys, mask) if noise is None else np.asarray(noise, dtype=np.float64)
    scale = np.asarray(scale, dtype=np.float64)
    R, nd = x0.shape[0], len(states)
    mean, weight, sigma = np.zeros((R, nd)), np.zeros((R, nd)), np.full(nd, math.nan)
    for j, s in enumerate(states):
        if s not in channels:
            c = rate_channel(model, s)
            if ts is not None and c in channels:
                sd = _rate_spread(np.asarray(ts), ys[..., list(channels).index(c)], np.asarray(mask, bool))
                if sd > 0:
                    weight[:, j] = scale[j] / sd
            continue
        c = channels.index(s)
        i_s = model.state_names.index(s)
        sigma[j] = noise[c]
        weight[:, j] = scale[j] / noise[c]
        mean[:, j] = (ys[:, 0, c] - x0[:, i_s]) / scale[j]
    return StartPrior(tuple(states), scale, mean, weight, sigma)


def _rate_spread(ts: np.ndarray, y: np.ndarray, mask: np.ndarray) -> float:
    """Standard deviation over the runs of a channel's zero-phase filtered derivative."""
    out = []
    for i in range(y.shape[0]):
        t, v = ts[i, mask[i]], y[i, mask[i]]
        try:
            out.append(smooth_and_derivative(t, v, Filter(), "rate")[1])
        except Exception:  # a run too short for the filter: its plain differences
            out.append(np.gradient(v, t) if v.size > 2 else np.zeros(0))
    d = np.concatenate(out) if out else np.zeros(0)
    return float(np.std(d)) if d.size > 2 else 0.0


class _StartSolver(eqx.Module):
    """Static owner of the compiled initial-state solve (hashable: the compile-cache key)."""

    out_idx: tuple[int, ...] = eqx.field(static=True)
    angle: tuple[bool, ...] = eqx.field(static=True)
    x_idx: tuple[int, ...] = eqx.field(static=True)
    integrator: AbstractIntegrator = eqx.field(static=True)
    steps: int = eqx.field(static=True, default=12)

    def residuals(self, model, d, t, u, y, mask, x0, scale, wc, pw, pm):
        x = x0.at[jnp.asarray(self.x_idx)].add(d * scale)
        sol = simulate(model, t, u, x, self.integrator)
        e = sol.ys[:, jnp.asarray(self.out_idx)] - y
        e = jnp.where(jnp.asarray(self.angle), jnp.arctan2(jnp.sin(e), jnp.cos(e)), e)
        good = (sol.valid & mask)[:, None]
        e = jnp.where(good, e / wc, 0.0) + jnp.where(((~sol.valid) & mask)[:, None], 1e3, 0.0)
        return jnp.concatenate([e.reshape(-1), pw * (d - pm)])

    def solve(self, model, ts, us, ys, mask, x0, scale, wc, pw, pm):
        """Levenberg–Marquardt over each run's offsets ``d`` (``vmap`` over runs; a fixed number of
        steps, a step accepted where it lowers the cost)."""

        def one(t, u, y, m, x, w, pm_):
            f = lambda d: self.residuals(model, d, t, u, y, m, x, scale, wc, w, pm_)  # noqa: E731

            def body(_, c):
                d, lam, r = c
                J = jax.jacfwd(f)(d)
                g = J.T @ r
                H = J.T @ J
                step = -jnp.linalg.solve(H + lam * (jnp.diag(jnp.diag(H)) + 1e-12 * jnp.eye(d.shape[0])), g)
                r_new = f(d + step)
                better = (r_new @ r_new < r @ r) & jnp.all(jnp.isfinite(r_new))
                return (jnp.where(better, d + step, d), jnp.where(better, lam * 0.3, lam * 10.0),
                        jnp.where(better, r_new, r))

            d0 = jnp.zeros(len(self.x_idx), dtype=t.dtype)
            d, _, _ = jax.lax.fori_loop(0, self.steps, body, (d0, jnp.asarray(1e-3, t.dtype), f(d0)))
            return x.at[jnp.asarray(self.x_idx)].add(d * scale)
        return jax.vmap(one)(ts, us, ys, mask, x0, pw, pm)


def _start_problem(model: AbstractModel, runs: Sequence[Run], channels: Sequence[str], flt: Filter,
                   integrator: AbstractIntegrator, noise: Mapping[str, float] | None):
    """The initial-state solve of :func:`estimate_starts` for ``runs`` (``channels`` the model's outputs, at least
    one, every run has them): ``(solver, args(wc), sig, x_data, ys, mask)``; ``args(wc)`` the compiled solve's
    arguments at channel scales ``wc``, one tuple per chunk of :data:`RUNS_PER_SOLVE` runs, ``sig`` the channels'
    sensor noise."""
    x_data = [np.asarray(initial_state(model, r, flt), dtype=np.float64) for r in runs]
    states = estimated_states(model, channels)
    n = max(r.n for r in runs)
    R, C = len(runs), len(channels)
    ts, us = np.zeros((R, n)), np.zeros((R, n, len(model.input_names)))
    ys, mask = np.zeros((R, n, C)), np.zeros((R, n), dtype=bool)
    for i, r in enumerate(runs):
        t = np.asarray(r.time, dtype=np.float64)
        dt_last = t[-1] - t[-2] if t.size > 1 else 1.0
        ts[i, : r.n], ts[i, r.n:] = t, t[-1] + dt_last * np.arange(1, n - r.n + 1)
        u = model_inputs(model, r)
        us[i, : r.n], us[i, r.n:] = u, u[-1]
        for j, c in enumerate(channels):
            y = np.asarray(r[c], dtype=np.float64)
            ys[i, : r.n, j] = np.unwrap(y) if c in model.angle_outputs else y
        mask[i, : r.n] = True
    x0 = np.stack(x_data)
    spread = np.asarray([max(float(np.std(ys[..., j][mask])), 1e-9) for j in range(C)])
    st_scale = state_scales(model, channels, spread, states)
    sig = (np.asarray([float(noise[c]) for c in channels]) if noise is not None else channel_noise(ys, mask))
    prior = start_prior(model, channels, ys, mask, x0, states, st_scale, sig, ts=ts)
    solver = _StartSolver(tuple(model.output_names.index(c) for c in channels),
                          tuple(c in model.angle_outputs for c in channels),
                          tuple(model.state_names.index(s) for s in states), integrator)
    f = lambda a: jnp.asarray(a, dtype=jnp.float64)  # noqa: E731
    # the run axis filled up to whole chunks with copies of the last run, masked (after every pooled quantity above)
    k = RUNS_PER_SOLVE
    idx = np.minimum(np.arange(-(-R // k) * k), R - 1)
    per_run = [f(ts[idx]), f(us[idx]), f(ys[idx]), jnp.asarray(mask[idx] & (np.arange(idx.size) < R)[:, None]),
               f(x0[idx]), f(prior.weight[idx]), f(prior.mean[idx])]

    def args(wc):
        return [(model, *(a[c:c + k] for a in per_run[:5]), f(st_scale), f(wc), *(a[c:c + k] for a in per_run[5:]))
                for c in range(0, idx.size, k)]
    return solver, args, sig, x_data, ys, mask


#: Runs per call of the compiled initial-state solve. The runs are independent problems (each its own offsets), so a
#: run set is solved in chunks of this many, the last one filled up with a copy of a run whose samples are all masked
#: (its output dropped): every run set of one length shares one program. A discovery's training runs (4) and held-out
#: runs (2) compiled two programs of the all-terms model, 9 s of CPU each from an empty cache.
RUNS_PER_SOLVE = 2


def start_request(model: AbstractModel, runs: Sequence[Run], channels: Sequence[str], *, flt: Filter = Filter(),
                  integrator: AbstractIntegrator = Diffrax()) -> list:
    """The :mod:`diffship.compiled` requests ``[(owner, name, args, static)]`` of :func:`estimate_starts` on
    ``runs`` (the program depends on the model's structure, the channels and the runs' count and length, not on
    values): compile it ahead (:func:`diffship.compiled.prefetch`) and the estimate finds it. Empty where nothing is
    estimated."""
    channels = tuple(c for c in channels if c in model.output_names)
    if not runs or not channels or not estimated_states(model, channels):
        return []
    solver, args, sig, *_ = _start_problem(model, runs, channels, flt, integrator, None)
    return [(solver, "solve", args(sig)[0], {})]


def estimate_starts(model: AbstractModel, runs: Sequence[Run], channels: Sequence[str],
                    scales: Mapping[str, float] | None = None, *, flt: Filter = Filter(),
                    integrator: AbstractIntegrator = Diffrax(), noise: Mapping[str, float] | None = None
                    ) -> list[np.ndarray]:
    """**The initial-state rule with the parameters held** (module docstring): each run's initial state,
    estimated over the whole run with the model as it is, for the metrics and held-out runs.

    Args:
        model: the model (its parameters are not changed).
        runs: the runs; each must have ``channels``.
        channels: the fitted channels (a fit's ``channels``); states outside them keep the data's value.
        scales: the channel scales ``w_c`` of the fit (``FitResult.channel_scales``). Default: each
            channel's residual RMS at the data's start times the square root of its correlation time
            (one simulation per run).
        flt: the filter of the data's initial states.
        integrator: the fit's integrator.
        noise: the sensor noise per channel (default: estimated from these runs, :func:`channel_noise`).
    """
    channels = tuple(c for c in channels if c in model.output_names)
    if not runs or not channels or not estimated_states(model, channels):
        return [np.asarray(initial_state(model, r, flt), dtype=np.float64) for r in runs]
    solver, args, sig, x_data, ys, mask = _start_problem(model, runs, channels, flt, integrator, noise)

    def solve(wc):
        parts = args(wc)
        fn, _ = compiled(solver, "solve", parts[0])
        out = np.concatenate([np.asarray(fn(*a)) for a in parts])
        return [out[i] if np.all(np.isfinite(out[i])) else x_data[i] for i in range(len(runs))]
    if scales is not None:
        return solve(np.asarray([float(scales[c]) for c in channels]))
    # without a fit's scales: the start estimated with the sensor noise as scales, then the scales of the
    # residuals from there (RMS times the square root of the correlation time), then the start again
    out = solve(sig)
    for _ in range(2):
        out = solve(default_scales(model, runs, channels, np.stack(out), ys, mask, integrator))
    return out


def default_scales(model: AbstractModel, runs: Sequence[Run], channels, x0, ys, mask, integrator) -> np.ndarray:
    r"""Channel scales without a fit: each channel's residual RMS from the starts ``x0`` times
    :math:`\sqrt{\tau_c}`, its correlation time in samples (the effective-sample weighting of a fit),
    at least the channel's sensor noise."""
    out_idx = [model.output_names.index(c) for c in channels]
    angle = np.asarray([c in model.angle_outputs for c in channels])
    errs = []
    for i, run in enumerate(runs):
        m = mask[i]
        sol = simulate_run(model, run, x0[i], integrator)
        e = np.asarray(sol.ys)[:, out_idx] - ys[i, m]
        e[:, angle] = np.arctan2(np.sin(e[:, angle]), np.cos(e[:, angle]))
        if not np.all(np.isfinite(e)) or not bool(sol.ok):
            e = np.where(np.isfinite(e), e, 0.0)
        errs.append(e)
    noise = channel_noise(ys, mask)
    out = []
    for j in range(len(channels)):
        rms = math.sqrt(float(np.mean(np.concatenate([e[:, j] ** 2 for e in errs]))))
        tau = correlation_time_of([e[:, j] for e in errs])
        out.append(max(rms * math.sqrt(tau), noise[j]))
    return np.asarray(out)


def correlation_time_of(series: Sequence[np.ndarray], max_lag: int = 400) -> float:
    """Integrated autocorrelation time (samples) of one channel pooled over runs, summed to the first negative lag
    (at most ``max_lag`` or a quarter of the shortest run); ≥ 1."""
    n_min = min(s.size for s in series)
    K = max(1, min(max_lag, n_min // 4))
    num, den = np.zeros(K + 1), 0.0
    for x in series:  # the lagged products Σ x_t x_{t+k} of every lag at once, by FFT (zero-padded: no wrap-around)
        x = np.asarray(x, dtype=np.float64) - np.mean(x)
        den += float(x @ x)
        m = 1 << int(2 * x.size - 1).bit_length()
        f = np.fft.rfft(x, m)
        num[1:] += np.fft.irfft(f * np.conj(f), m)[1:K + 1]
    rho = num[1:] / den if den > 0 else np.zeros(K)
    neg = np.flatnonzero(rho < 0)
    rho = rho[: neg[0]] if neg.size else rho
    return max(1.0, 1.0 + 2.0 * float(np.sum(rho)))


def cost_of_data_starts(model: AbstractModel, runs: Sequence[Run], channels: Sequence[str],
                        scales: Mapping[str, float], *, flt: Filter = Filter(),
                        integrator: AbstractIntegrator = Diffrax()) -> str:
    """What taking the data's initial states as exact costs a fit (``--x0 data``), in one sentence: the
    weighted output error ½Σ(e/w)² from the data's starts against the starts of this rule at the same
    parameters, and how many sensor-noise levels the measured starts are from the estimated ones."""
    channels = tuple(c for c in channels if c in model.output_names)
    states = estimated_states(model, channels)
    if not states:
        return ""
    x_data = [np.asarray(initial_state(model, r, flt), dtype=np.float64) for r in runs]
    x_est = estimate_starts(model, runs, channels, scales, flt=flt, integrator=integrator)
    idx = [model.output_names.index(c) for c in channels]
    angle = np.asarray([c in model.angle_outputs for c in channels])

    noise = {c: max(noise_floor(np.concatenate([np.unwrap(r[c]) if c in model.angle_outputs else np.asarray(r[c])
                                                for r in runs])), 1e-12) for c in channels}

    def cost(xs):  # the rule's objective: weighted output errors and the measured starts' prior rows
        total = 0.0
        for run, x in zip(runs, xs):
            sol = simulate_run(model, run, x, integrator)
            y = np.stack([np.unwrap(run[c]) if c in model.angle_outputs else np.asarray(run[c]) for c in channels], 1)
            e = np.asarray(sol.ys)[:, idx] - y
            e[:, angle] = np.arctan2(np.sin(e[:, angle]), np.cos(e[:, angle]))
            total += 0.5 * float(np.sum((e / np.asarray([scales[c] for c in channels])) ** 2))
            total += 0.5 * sum(((x[model.state_names.index(s)] - y[0, channels.index(s)]) / noise[s]) ** 2
                               for s in states if s in channels)
        return total
    c_data, c_est = cost(x_data), cost(x_est)
    worst = max(((abs(xd[model.state_names.index(s)] - xe[model.state_names.index(s)]) / max(noise[s], 1e-12), s)
                 for xd, xe in zip(x_data, x_est) for s in states if s in channels), default=(0.0, ""))
    text = (f"--x0 data: every run starts at its filtered first sample, taken as exact; at these parameters the "
            f"one initial-state rule's starts lower its objective (weighted output errors and the first samples' "
            f"noise) from {c_data:.6g} to {c_est:.6g} ({100 * (c_est - c_data) / max(c_data, 1e-300):+.1f} %)")
    if worst[1]:
        text += f", and moves the start of {worst[1]} by {worst[0]:.1f} sensor-noise levels"
    return text + ": a noisy first sample biases every estimate; the default (--x0 estimate) fits the starts"
