r"""Prediction-error method: an extended Kalman filter's innovations, minimised by the one LM.

Output error assumes the only noise is on the sensors: the simulated state follows the model
from the first sample to the last. At sea (wind gusts, waves, current changes) the state also
receives unmeasured forces, the simulation drifts away from the measured one for reasons no
parameter can fix, and the output-error estimates are biased. The prediction-error method
(Ljung 1999, ch. 7; Åström 1980) predicts each sample from the past *measured* samples instead:
an extended Kalman filter over the model's vector field,

.. math::
    x_{k+1} = F_k(x_k; \theta) + w_k,\quad w_k \sim \mathcal N(0, Q\,\Delta t_k), \qquad
    y_k = h(x_k, u_k; \theta) + v_k,\quad v_k \sim \mathcal N(0, R),

with :math:`F_k` one step of the fit's integrator over the sample interval (first-order-hold
inputs, exactly as in simulation) and :math:`A_k = \partial F_k/\partial x`,
:math:`H_k = \partial h/\partial x` by ``jax.jacfwd``. The filter (one ``lax.scan`` per run,
``vmap`` over runs, Joseph-form update) gives the innovations
:math:`e_k = y_k - h(\hat x_{k|k-1})` and their covariances
:math:`S_k = H_k P_{k|k-1} H_k^\top + R`. The negative log-likelihood is

.. math::
    \ell(\theta, Q, R) = \tfrac12 \sum_k \big(\varepsilon_k^\top\varepsilon_k + \log\det S_k\big) + \text{const},
    \qquad \varepsilon_k = L_k^{-1} e_k,\ S_k = L_k L_k^\top.

**Disturbance model** (:mod:`diffship.fit.disturbance`). With ``disturbance="ou"`` (default) the unmeasured
forces are not white: each state in ``process_states`` (velocities, yaw rate) gets an extra filter state
:math:`w_i` added to its rate, :math:`\dot x_i = f_i(x, u) + w_i`, an Ornstein–Uhlenbeck process
:math:`\dot w = -w/\tau + \sqrt{2/\tau}\,q\,\xi(t)` (stationary standard deviation ``q``
[state unit/s], one time constant ``τ`` estimated with the noise levels). Wind and wave drift
forces are coloured like this; a white-noise filter on such data leaves correlated innovations
and biased estimates (measured on a Nomoto test: 2–4 standard errors off). ``"wave"``: a narrow-band
resonator (period, damping estimated); ``"walk"``: a random walk; ``"white"``: white process noise
:math:`Q`. Under feedback (an autopilot reacting to the wave yaw) only a right noise model gives
consistent dynamics (Ljung 1999, §13.4: the direct approach).

**Least-squares form.** The residual rows are the normalised innovations :math:`\varepsilon_k`
(``n_c`` per sample). When the noise covariances are estimated, one more row per sample,
:math:`\rho_k = \sqrt{\log\det S_k - \log\det R_{\min}}`, makes :math:`\tfrac12\lVert r\rVert^2`
equal to :math:`\ell` up to a constant. The root is always real because the measurement
variances are parametrised with a floor, :math:`R_c = r_{\min,c}^2 + (r_c e^{\eta_c})^2`, so
:math:`S_k \succeq R \succeq R_{\min}` and :math:`\det S_k \ge \det R_{\min}` (the floor is
``noise_floor`` times the channel spread; with a 10⁻⁴ floor the argument is ~18 per channel,
far from the root's singularity at 0). This keeps the problem a sum of squares, so the same
Levenberg–Marquardt, parameter scaling, bounds and priors as output error apply unchanged (a
subclass of :class:`~diffship.fit.kernel.Kernel` that overrides only ``residuals``). With
given covariances the log-determinant is constant and only :math:`\varepsilon` is used.

Noise parametrisation (diagonal, square-root with floors): process-noise standard deviations
:math:`q_i = q_{0,i}\sqrt{q_f^2 + \eta_{q,i}^2}` [state unit/√s] on ``process_states`` (default: the
states of the fitted channels that are not kinematic — x0, y0, psi are integrals of velocities),
measurement standard deviations :math:`\sqrt{R_c} = \sqrt{r_{\min,c}^2 + (r_{0,c}\eta_{r,c})^2}`
per fitted channel; the unknowns start at :math:`\eta = 1`. Not a logarithm on purpose: a noise level the data
cannot tell from zero (no process noise in calm water) has its optimum on the floor, which a logarithmic
parameter approaches by ever smaller steps towards −∞ (measured: 200 LM steps without meeting the tolerances
on a Nomoto problem); here it is an ordinary smooth minimum at :math:`\eta = 0` and the fit converges.
Starts: the measurement noise from each channel's ``std(Δy)/√2``, the process noise ``q_start`` times each
state's spread per √s: the fluctuations in the sensor. Sampled slowly against the disturbance, ``std(Δy)`` is
the disturbance itself and that start ends in a local optimum whose innovations their past predicts. Then
(:func:`~diffship.fit.covariance.predictability` over :data:`PREDICTABLE`) the fit solves again from
:func:`disturbance_start` and keeps the higher likelihood (the full :math:`\ell`). Measured on a ship's autopilot
log (``benchmarks/results/at_sea_hakusan.md``): −log L per sample −1.93 → −2.94, yaw rate one sample ahead
1.96 → 0.69 °/s.

**Standard errors** are from the innovation rows only, :math:`(J_\varepsilon^\top J_\varepsilon)^{-1}`
with unit variance (the innovations are normalised by their own predicted covariance), joint
over parameters and noise levels, and posterior when priors are used. The filter models the
process noise as white; coloured disturbances (e.g. Ornstein–Uhlenbeck forces) make the
innovations slightly correlated, which PEM tolerates for open-loop data (Ljung 1999, Thm 8.4:
the dynamics are still estimated consistently with a wrong noise model) at some cost in efficiency
and in the honesty of the standard errors — measured in ``benchmarks/estimators.py``.

References:
    L. Ljung, *System Identification: Theory for the User*, 2nd ed., Prentice Hall 1999.
    K. J. Åström, "Maximum likelihood and prediction error methods", Automatica 16 (1980).
    S. Särkkä, *Bayesian Filtering and Smoothing*, Cambridge 2013, §5.2 (extended Kalman filter).
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable, Mapping, Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from ..data import Run
from ..errors import FitError
from ..models import AbstractModel
from ..params import ParamSpec
from . import disturbance as dist
from . import status as st
from .covariance import predictability
from .driver import fit
from .ekf import FilterPass, ekf
from .estimator import OnOutputError, Problem, Solved
from .identifiability import per_scale_columns
from .kernel import PENALTY, Kernel, KernelData, kernel_data
from .output_error import OutputErrorOptions
from .priors import prior_arrays
from .problem import make_batch
from .result import FitResult
from .weights import channel_spread, x0_scales

__all__ = ["PredictionError", "PredictionErrorOptions", "disturbance_start", "PREDICTABLE", "SENSOR_SHARE", "PEKernel",
           "PEData", "FilterPass", "ekf", "fit_prediction_error", "KINEMATIC_STATES"]

#: Process-noise floor relative to its start (:math:`q_f`; module docstring).
Q_FLOOR = 1e-3

#: Share of the innovations' variance their own past may predict (AR(4)) before the fit also tries the
#: disturbance-dominated noise start (module docstring). White innovations give about 4/N.
PREDICTABLE = 0.25

#: The measurement noise of the disturbance-dominated start, relative to the first start's.
SENSOR_SHARE = 0.1

#: States that are integrals of other states (no process noise on them by default).
KINEMATIC_STATES = ("x0", "y0", "psi")


@dataclasses.dataclass(frozen=True)
class PredictionErrorOptions:
    """How the prediction-error fit models the noise.

    Attributes:
        process_states: states that receive process noise (default: see the module docstring).
        estimate_noise: estimate the noise levels (``True``) or hold them at the given values.
        process_noise: process-noise standard deviation per state [state unit/√s]; the start
            (or the fixed value) where given.
        measurement_noise: measurement standard deviation per channel (model units); the start
            (or the fixed value) where given.
        q_start: default process-noise start, as a fraction of each state's spread per √s.
        p0_rel: initial state standard deviation, as a fraction of each state's spread.
        noise_floor: measurement standard-deviation floor, as a fraction of the channel spread.
        disturbance: ``"ou"`` (default): the process noise is an Ornstein–Uhlenbeck disturbance
            added to the rates of ``process_states`` (extra filter states, time constant
            estimated with the noise levels; ``process_noise`` is then its stationary standard
            deviation [state unit/s]); ``"wave"``, ``"walk"``: :mod:`diffship.fit.disturbance`; ``"white"``:
            white noise on those states [state unit/√s].
        tau, wave_period, wave_damping: starts (or fixed values) of the hyper-parameters [s, s, -]; the wave's
            period ``None``: :func:`~diffship.fit.disturbance.spectral_period` of the fitted channels.
    """

    process_states: tuple[str, ...] | None = None
    estimate_noise: bool = True
    process_noise: Mapping[str, float] | None = None
    measurement_noise: Mapping[str, float] | None = None
    q_start: float = 0.01
    p0_rel: float = 0.1
    noise_floor: float = 1e-4
    disturbance: str = "ou"
    tau: float = 10.0
    wave_period: float | None = None
    wave_damping: float = 0.1

    def __post_init__(self):
        for what, d in (("process_noise", self.process_noise), ("measurement_noise", self.measurement_noise)):
            for k, v in (d or {}).items():
                if not (math.isfinite(v) and v > 0):
                    raise FitError(f"prediction error: {what}[{k!r}] must be a positive standard deviation, got {v!r}")
        if self.disturbance not in dist.KINDS:
            raise FitError(f"prediction error: disturbance must be one of {', '.join(dist.KINDS)}, got {self.disturbance!r}")
        for what, v in (("time constant tau", self.tau), ("wave period", self.wave_period or 1.0),
                        ("wave damping", self.wave_damping)):
            if not (math.isfinite(v) and v > 0):
                raise FitError(f"prediction error: the disturbance {what} must be positive, got {v!r}")
        if self.process_states is not None:
            object.__setattr__(self, "process_states", tuple(self.process_states))


class PEData(KernelData):
    """:class:`~diffship.fit.kernel.KernelData` plus the noise model (arrays; no recompiles).

    Attributes:
        q_scale: process-noise standard deviation at ``η_q = 1`` per noisy state [unit/√s].
        r_scale: measurement standard deviation (above the floor) at ``η_r = 1`` per channel.
        r_floor: measurement standard-deviation floor per channel.
        eta_q, eta_r: the noise unknowns used when the noise is not estimated.
        P0: initial state covariance ``(n_x, n_x)``.
        hyper0: the disturbance's hyper-parameters at ``ζ = 0`` (:data:`~diffship.fit.disturbance.HYPER`, NaN-padded).
    """

    q_scale: Float[Array, " n_q"]
    r_scale: Float[Array, " n_c"]
    r_floor: Float[Array, " n_c"]
    eta_q: Float[Array, " n_q"]
    eta_r: Float[Array, " n_c"]
    P0: Float[Array, "n_x n_x"]
    hyper0: Float[Array, " 2"]


class PEKernel(Kernel):
    """The one kernel with Kalman-filter innovations as residuals (module docstring).

    Unknowns ``z = (z_θ, η_q, η_r)`` when the noise is estimated, ``z_θ`` otherwise.
    """

    q_idx: tuple[int, ...] = eqx.field(static=True, default=())
    estimate_noise: bool = eqx.field(static=True, default=True)
    disturbance: str = eqx.field(static=True, default="ou")

    @property
    def coloured(self) -> bool:  # the disturbance has filter states of its own
        return self.disturbance != "white"

    @property
    def n_noise(self) -> int:
        """Number of noise unknowns (0 when the noise is given)."""
        if not self.estimate_noise:
            return 0
        return len(self.q_idx) + len(self.out_idx) + dist.n_hyper(self.disturbance)

    def noise(self, z: Float[Array, " n_z"], data: PEData):
        """``(q, r, h)``: process standard deviation per noisy state (white: [unit/√s]; coloured:
        the disturbance's stationary sd [unit/s]), measurement variance per channel, and the
        disturbance's hyper-parameters (:func:`~diffship.fit.disturbance.hyper_values`: ``τ``, or the wave's
        period and damping; NaN where none)."""
        n, n_q, n_c, n_h = self.n_theta, len(self.q_idx), len(self.out_idx), dist.n_hyper(self.disturbance)
        if self.estimate_noise:
            eta_q, eta_r, zeta = z[n:n + n_q], z[n + n_q:n + n_q + n_c], z[n + n_q + n_c:n + n_q + n_c + n_h]
        else:
            eta_q, eta_r, zeta = data.eta_q, data.eta_r, jnp.zeros(n_h)
        q = data.q_scale * jnp.sqrt(Q_FLOOR ** 2 + eta_q ** 2)
        r = data.r_floor ** 2 + (data.r_scale * eta_r) ** 2
        return q, r, dist.hyper_values(self.disturbance, zeta, data.hyper0)

    def filter(self, z: Float[Array, " n_z"], data: PEData, keep: bool = False) -> FilterPass:
        """The filter over every run (``vmap``) at ``z`` (coloured: states ``(x, w)``)."""
        f, h, q_var, r, P0, x0 = self.system(z, data)
        return jax.vmap(lambda t, u, y, m, x: ekf(f, h, self.integrator, self.angle, q_var, r, t, u, y, m, x, P0,
                                                  keep))(data.ts, data.us, data.ys, data.mask, x0)

    def system(self, z: Float[Array, " n_z"], data: PEData):
        """``(f, h, q_var, r, P0, x0)``: the filter's vector field ``f(t, x, u)`` and fitted channels ``h(x, u)`` on
        the augmented state ``(x, w)``, its process-noise intensities, measurement variances, initial covariance and
        the runs' initial states (:mod:`diffship.fit.ahead` predicts with the same ``f`` and ``h``)."""
        model = self.model_at(z, data)
        q, r, hyp = self.noise(z, data)
        oi = jnp.asarray(self.out_idx)
        qi = jnp.asarray(self.q_idx, dtype=int)
        n_x, n_q, kind = data.x0.shape[1], len(self.q_idx), self.disturbance
        if self.coloured:
            def f(t, xa, u):
                x, w = xa[:n_x], xa[n_x:]
                return jnp.concatenate([model.vector_field(t, x, u).at[qi].add(w[:n_q]),
                                        dist.extra_rates(kind, w, hyp, n_q)])

            def h(xa, u):
                return model.observe(xa[:n_x], u)[oi]

            # white floor on the model states keeps P regular; the disturbance states carry the process noise
            q_var = jnp.concatenate([jnp.zeros(n_x).at[qi].set((Q_FLOOR * data.q_scale) ** 2),
                                     dist.extra_noise(kind, q, hyp)])
            P0 = jax.scipy.linalg.block_diag(data.P0, jnp.diag(dist.extra_p0(kind, q, hyp)))
            x0 = jnp.concatenate([data.x0, jnp.zeros((data.x0.shape[0], dist.n_extra(kind, n_q)))], axis=1)
        else:
            def f(t, x, u):
                return model.vector_field(t, x, u)

            def h(x, u):
                return model.observe(x, u)[oi]

            q_var, P0, x0 = jnp.zeros(n_x).at[qi].set(q ** 2), data.P0, data.x0
        return f, h, q_var, r, P0, x0

    def residuals(self, z: Float[Array, " n_z"], data: PEData) -> Float[Array, " m"]:
        fp = self.filter(z, data)
        rows = [fp.eps.reshape(-1)]
        if self.estimate_noise:
            c = fp.logdet - jnp.sum(jnp.log(data.r_floor ** 2))
            rows.append(jnp.where(data.mask, jnp.sqrt(jnp.maximum(c, 0.0) + 1e-12), 0.0).reshape(-1))
        return self.with_prior_rows(jnp.concatenate(rows), z, data)


def _process_states(model: AbstractModel, channels: Sequence[str], po: PredictionErrorOptions) -> tuple[str, ...]:
    if po.process_states is not None:
        bad = [s for s in po.process_states if s not in model.state_names]
        if bad:
            raise FitError(f"prediction error: process_states {', '.join(bad)} are not states of model {model.name} "
                           f"({', '.join(model.state_names)})")
        return po.process_states
    out = tuple(s for s in model.states_for_channels(channels) if s not in KINEMATIC_STATES)
    return out or tuple(s for s in model.state_names if s not in KINEMATIC_STATES)


def pe_problem(model: AbstractModel, runs: Sequence[Run], spec: ParamSpec, channels, o: OutputErrorOptions,
               po: PredictionErrorOptions):
    """``(kernel, data, batch, process_states)`` of the prediction-error problem at the noise starts."""
    batch = make_batch(model, runs, channels, o.flt)
    pstates = _process_states(model, batch.channels, po)
    unknown = [c for c in (po.measurement_noise or {}) if c not in batch.channels]
    unknown += [s for s in (po.process_noise or {}) if s not in pstates]
    if unknown:
        raise FitError(f"prediction error: noise given for {', '.join(unknown)}, which are not fitted channels "
                       f"({', '.join(batch.channels)}) or noisy states ({', '.join(pstates)})")
    spread = channel_spread(batch)
    sx = x0_scales(model, batch, model.state_names)
    q0 = np.asarray([(po.process_noise or {}).get(s, po.q_start * sx[model.state_names.index(s)]) for s in pstates])
    r0 = []
    for j, c in enumerate(batch.channels):
        d = np.concatenate([np.diff(batch.ys[i, : batch.lengths[i], j]) for i in range(len(runs))])
        r0.append((po.measurement_noise or {}).get(c, max(float(np.std(d)) / math.sqrt(2.0), 1e-3 * spread[j])))
    floor = po.noise_floor * spread
    r_scale = np.sqrt(np.maximum(np.asarray(r0) ** 2 - floor ** 2, (0.1 * floor) ** 2))
    kernel = PEKernel(
        spec=spec.structural(),
        out_idx=tuple(model.output_names.index(c) for c in batch.channels),
        angle=tuple(c in model.angle_outputs for c in batch.channels),
        integrator=o.integrator, q_idx=tuple(model.state_names.index(s) for s in pstates),
        estimate_noise=po.estimate_noise, disturbance=po.disturbance,
    )
    base = kernel_data(model, batch.ts, batch.us, batch.ys, batch.mask, batch.x0, spread)
    fields = {f.name: getattr(base, f.name) for f in dataclasses.fields(KernelData)}
    f64 = lambda a: jnp.asarray(a, dtype=jnp.float64)  # noqa: E731
    data = PEData(**fields, q_scale=f64(q0), r_scale=f64(r_scale), r_floor=f64(floor), eta_q=f64(np.ones(len(q0))),
                  eta_r=f64(np.ones(len(r0))), P0=f64(np.diag((po.p0_rel * sx) ** 2)),
                  hyper0=f64(dist.hyper_starts(
                      po.disturbance, po.tau, po.wave_period, po.wave_damping, batch)))
    return kernel, data, batch, pstates


def disturbance_start(model: AbstractModel, kernel: PEKernel, data: PEData, batch, po: PredictionErrorOptions):
    r"""``data`` rescaled to the disturbance-dominated start at ``η = 1`` (``None`` where the noise or its start is
    given): each state's disturbance at its spread per time scale of the process, :math:`q_i = s_i/T_d`
    (:math:`T_d = T_w/2\pi`, ``τ``, or 1 s), the measurement noise at :data:`SENSOR_SHARE` of the first start's."""
    if not (po.estimate_noise and kernel.n_noise) or po.process_noise or po.measurement_noise:
        return None
    sx, h0 = x0_scales(model, batch, model.state_names), np.asarray(data.hyper0)
    t_d = {"wave": h0[0] / (2 * math.pi), "ou": h0[0]}.get(kernel.disturbance, 1.0)
    q_hi = np.maximum(np.asarray([sx[i] for i in kernel.q_idx]) / t_d, np.asarray(data.q_scale))
    return data.replace(q_scale=jnp.asarray(q_hi), r_scale=SENSOR_SHARE * data.r_scale)


def _reparametrised(z: np.ndarray, n: int, n_q: int, n_c: int, src: PEData, dst: PEData) -> np.ndarray:
    """The unknowns ``z`` (``n`` parameters first) of ``src``'s noise parametrisation in ``dst``'s: the same levels."""
    a = {k: np.asarray(getattr(src, k)) for k in ("q_scale", "r_scale", "r_floor")}
    b = {k: np.asarray(getattr(dst, k)) for k in ("q_scale", "r_scale", "r_floor")}
    q2 = (a["q_scale"] / b["q_scale"]) ** 2 * (Q_FLOOR ** 2 + z[n:n + n_q] ** 2)
    r = a["r_floor"] ** 2 + (a["r_scale"] * z[n + n_q:n + n_q + n_c]) ** 2
    return np.concatenate([z[:n], np.sqrt(np.maximum(q2 - Q_FLOOR ** 2, 0.0)),
                           np.sqrt(np.maximum(r - b["r_floor"] ** 2, 0.0)) / b["r_scale"], z[n + n_q + n_c:]])


@dataclasses.dataclass(frozen=True)
class PredictionError(OnOutputError):
    """The prediction-error method (module docstring): the settings of the estimator.

    Attributes:
        oe: what output error would use and this estimator shares — the integrator, the filter for
            the initial states, the LM limits and the priors (``estimate_x0``, ``weights``,
            ``channel_scales``, ``gntol``, ``warmup`` and ``effective_samples`` do not apply: the
            filter estimates the states, innovations are whitened by their own covariance, and the
            plain step/cost stopping tests are used — see :meth:`first_solves`).
        noise: the noise model (:class:`PredictionErrorOptions`).
    """

    method = "prediction_error"

    oe: OutputErrorOptions = OutputErrorOptions()
    noise: PredictionErrorOptions = PredictionErrorOptions()

    def describe(self) -> str:
        return "prediction error"

    def prepare(self, model, runs, spec, channels, priors, say) -> Problem:
        o, po = self.oe, self.noise
        kernel, data, batch, pstates = pe_problem(model, runs, spec, channels, o, po)
        p_mean, p_w = prior_arrays(priors, spec)
        if np.any(p_w):
            data = data.replace(prior_mean=jnp.asarray(p_mean), prior_w=jnp.asarray(p_w))
        n_p, n_noise = len(spec.free_names), kernel.n_noise
        # The plain step/cost stopping tests, without output error's Gauss–Newton-step check (gntol): the noise
        # unknowns have flat, non-quadratic directions where the data carry no disturbance (the time constant; a
        # process-noise level on its floor), along which that step is spurious. On the calm-water Nomoto test
        # (tests/fit/test_prediction_error.py) it predicted a 0.36-standard-error move of K, T1, δ0 at the optimum,
        # where 178 further LM steps moved them by under 1e-4 standard errors. The solve keeps its last Jacobian
        # (the covariance's, :meth:`finish`): no Jacobian program, which compiles as long as the solve.
        lm = dict(max_steps=o.max_steps, rtol=o.rtol, atol=o.atol, gntol=float("inf"), jacobian=True)
        say(f"prediction error: compiling the Kalman-filter fit of {model.name} ({n_p} parameters, {n_noise} noise "
            f"levels, {len(runs)} runs, {o.integrator.describe()})...")
        res_fn, compile_s = kernel.compiled("residuals", np.ones(n_p + n_noise), data)
        names = tuple([*(f"process noise on {s_}" for s_ in pstates),
                       *(f"measurement noise on {ch}" for ch in batch.channels),
                       *(dist.LABEL[h] for h in dist.HYPER[po.disturbance])][:n_noise])
        return Problem(model=model, spec=spec, runs=tuple(runs), channels=batch.channels, n_nuisance=n_noise,
                       nuisance_names=names, priors=priors, compile_seconds=compile_s,
                       state=dict(kernel=kernel, data=data, batch=batch, pstates=pstates, res_fn=res_fn,
                                  lm=lm, n_eps=int(np.prod(data.ys.shape)), nuisance0=np.ones(n_noise),
                                  noise_alt=disturbance_start(model, kernel, data, batch, po),
                                  integrator=o.integrator, n_rows=batch.n_residuals))

    def start_cost(self, problem, z) -> float:
        st_ = problem.state
        r = np.asarray(st_["res_fn"](jnp.asarray(z), st_["data"]))
        c = 0.5 * float(np.sum(r * r))
        return c if math.isfinite(c) and not np.any(np.abs(r[:st_["n_eps"]]) >= PENALTY) else math.inf

    def _solves(self, problem, z0s, say, label="prediction error", data=None):
        """Solve from each start; the wave's period and damping held at their starts first (narrow band first:
        released while the dynamics and noise levels are still poor, a wave broadens into a white-like disturbance
        that the steering's response then hides in; measured on an autopilot in waves). Every solve runs the
        batched LM's programs with a mask of free unknowns, so that the held and the free solve share one compiled
        program (:meth:`~diffship.fit.kernel.Kernel.solve_many`). ``(z, cost, steps, result, r, J)`` per start."""
        st_ = problem.state
        kernel, data = st_["kernel"], st_["data"] if data is None else data
        if kernel.disturbance == "wave" and kernel.n_noise:
            held = np.broadcast_to(np.arange(z0s.shape[1]) < z0s.shape[1] - 2, z0s.shape)  # period, damping last
            z0s = np.stack([np.asarray(o_[0]) for o_ in kernel.solve_many(
                z0s, data, free=held, progress=say, label=f"{label}, wave held", **st_["lm"])])
        res, free = [], np.ones(z0s.shape, bool)
        for z, result, k, r, J in kernel.solve_many(z0s, data, free=free, progress=say, label=label, **st_["lm"]):
            r = np.asarray(r)
            c = 0.5 * float(r @ r) if np.all(np.abs(r[:st_["n_eps"]]) < PENALTY) else math.inf  # NaN, blow-up: inf
            res.append((np.asarray(z), c if math.isfinite(c) else math.inf, int(k), result, r, np.asarray(J)))
        return res

    def first_solves(self, problem, zs, say):
        st_, t0 = problem.state, time.perf_counter()
        z0s = np.stack([np.asarray(z) for z in (zs[:1] if self.oe.choose == "first" else zs)])
        outs = self._solves(problem, z0s, say)
        b = int(np.argmin([o_[1] for o_ in outs]))
        st_["noise_note"], st_["noise_start"] = None, "sensor"
        alt, n_c = st_.get("noise_alt"), len(st_["batch"].channels)
        share = predictability(outs[b][4][:st_["n_eps"]], st_["batch"].mask, n_c) if alt is not None else 0.0
        if math.isfinite(outs[b][1]) and share > PREDICTABLE:  # module docstring: the disturbance-dominated start
            say(f"prediction error: {100 * share:.0f} % of the innovations' variance is predictable from their past; "
                "solving again from a disturbance-dominated noise start...")
            k, n_h = st_["kernel"], dist.n_hyper(st_["kernel"].disturbance)
            z_alt = np.concatenate([z0s[b][:k.n_theta], np.ones(len(k.q_idx) + n_c), np.zeros(n_h)])
            o_alt = self._solves(problem, z_alt[None], say, label="prediction error, disturbance start", data=alt)[0]
            o_alt = (_reparametrised(o_alt[0], k.n_theta, len(k.q_idx), n_c, alt, st_["data"]), *o_alt[1:5], None)
            won, d = o_alt[1] < outs[b][1], (o_alt[1] - outs[b][1]) / int(st_["batch"].mask.sum())
            st_["noise_note"] = (
                f"noise start: {100 * share:.0f} % of the innovations' variance at the first optimum was predictable "
                f"from their past (AR(4)); from a disturbance-dominated start (process noise at each state's spread "
                f"per time scale, sensor noise a tenth) -log L per sample changes by {d:+.3g}"
                f"{'' if math.isfinite(d) else ' (its filter diverges)'}: "
                + ("kept" if won else "the first kept; its innovations stay predictable: try another --disturbance"))
            st_["noise_start"], outs[b] = ("disturbance", o_alt) if won else ("sensor", outs[b])
        st_["pe_s"] = time.perf_counter() - t0
        st_["results"], st_["zs"], st_["jacs"] = [o_[3] for o_ in outs], [o_[0] for o_ in outs], [o_[5] for o_ in outs]
        return [o_[:3] for o_ in outs]

    def residuals(self, problem, z) -> np.ndarray:
        st_ = problem.state
        return np.asarray(st_["res_fn"](jnp.asarray(z), st_["data"]))[: st_["n_eps"]]

    def finish(self, problem, z, steps, say) -> Solved:
        st_, po = problem.state, self.noise
        kernel, data, batch, pstates = st_["kernel"], st_["data"], st_["batch"], st_["pstates"]
        i = next(k for k, zz in enumerate(st_["zs"]) if np.array_equal(zz, z))
        z = np.array(z)
        hyper = dist.HYPER[po.disturbance] if po.estimate_noise else ()
        edge = []
        for j, name in enumerate(hyper):
            z[len(z) - len(hyper) + j] = v = float(np.clip(z[len(z) - len(hyper) + j], *dist.CLIP[name]))
            edge += [dist.LABEL[name]] if min(abs(v - b_) for b_ in dist.CLIP[name]) < 1e-6 else []
        spec, r = problem.spec, np.asarray(st_["res_fn"](jnp.asarray(z), data))
        J_all = st_["jacs"][i]  # the solve's, at its last accepted point; elsewhere (a clipped or mapped z) formed here
        if J_all is None or not np.array_equal(z, st_["zs"][i]) or not np.any(J_all):
            J_all = np.asarray(kernel.call("jacobian", z, data))
        J_all = J_all * per_scale_columns(spec, z, len(z))
        J_eps, J_prior, r_eps, r_prior = J_all[:st_["n_eps"]], kernel.split(J_all, data)[1], r[:st_["n_eps"]], \
            kernel.split(r, data)[1]
        q, rv, hyp = (np.asarray(a) for a in kernel.noise(jnp.asarray(z), data))
        process_sd = {s_: float(v) for s_, v in zip(pstates, q)}
        meas_sd = {ch: float(math.sqrt(v)) for ch, v in zip(batch.channels, rv)}
        eps, mask = r_eps.reshape(data.ys.shape), batch.mask
        white = {ch: float(np.sqrt(np.mean(eps[..., j][mask] ** 2))) for j, ch in enumerate(batch.channels)}
        fp = kernel.filter(jnp.asarray(z), data)
        result = st.as_diffship(st_["results"][i])
        if not bool(np.all(np.asarray(fp.valid)[mask])):
            result = st.RESULTS.filter_diverged
        messages = [f"extended Kalman filter: process noise on {', '.join(pstates)}; noise levels "
                    + ("estimated" if po.estimate_noise else "given"),
                    "estimated noise: measurement sd " + ", ".join(f"{k} {v:.3g}" for k, v in meas_sd.items())
                    + (f"; disturbance ({dist.describe(po.disturbance, hyp)}, added to the rates of " + ", ".join(pstates)
                       + ") sd " if kernel.coloured else "; process sd per √s ")
                    + ", ".join(f"{k} {v:.3g}" for k, v in process_sd.items())]
        messages += [st_["noise_note"]] if st_.get("noise_note") else []
        if edge:  # nothing silent: a hyper-parameter held by its bound is not estimated
            messages.append(f"{', '.join(edge)} on its bound ({dist.bounds_text(po.disturbance, data.hyper0)}): the "
                            f"disturbance is not a process of this kind in that range; compare another --disturbance")
        return Solved(
            z=z, r_data=r_eps, J_data=J_eps, J_extra=J_prior, r_extra=r_prior, result=result, steps=steps,
            seconds=st_["pe_s"], compile_seconds=0.0, cost=0.5 * float(np.sum(r_eps ** 2)),
            channel_scales={ch: float(s_) for ch, s_ in zip(batch.channels, np.asarray(data.scales))},
            noise_std=meas_sd, initial_states=tuple(batch.x0), run_names=batch.names, variance=1.0,
            dof=int(mask.sum()) * len(batch.channels) - len(z), kind="auto", mask=np.asarray(mask),
            n_channels=len(batch.channels), prior_cost=0.5 * float(np.sum(r_prior ** 2)), messages=tuple(messages),
            info={"measurement_sd": meas_sd, "process_sd": process_sd, "process_states": pstates,
                  "disturbance": po.disturbance, "disturbance_tau": float(hyp[0]) if po.disturbance == "ou" else math.nan,
                  **({"wave_period": float(hyp[0]), "wave_damping": float(hyp[1])} if po.disturbance == "wave" else {}), "estimate_noise": po.estimate_noise,
                  "noise_start": st_.get("noise_start", "sensor"), "innovation_rms": white, "integrator": self.oe.integrator.describe()})


def fit_prediction_error(
    model: AbstractModel,
    runs: Sequence[Run],
    *,
    spec: ParamSpec | None = None,
    starts: Sequence[Mapping[str, float]] | Mapping[str, Mapping[str, float]] = (),
    channels: Sequence[str] | None = None,
    options: OutputErrorOptions = OutputErrorOptions(),
    noise: PredictionErrorOptions = PredictionErrorOptions(),
    progress: Callable[[str], None] | None = None,
    n_starts: int | None = 1,
    throw: bool = True,
) -> FitResult:
    """Fit ``model`` to ``runs`` by the prediction-error method: :func:`diffship.fit.fit` with
    :class:`PredictionError` (``options`` what output error would use, ``noise`` the noise model).
    Returns a :class:`~diffship.fit.FitResult` (``method="prediction_error"``) whose ``info`` holds
    the estimated noise levels (``measurement_sd`` per channel, ``process_sd`` per state per √s)."""
    return fit(model, runs, PredictionError(oe=options, noise=noise), spec=spec, starts=starts, n_starts=n_starts,
               channels=channels, progress=progress, throw=throw)
