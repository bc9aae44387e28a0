r"""Bootstrap intervals for output-error fits, all resamples refitted in one batch.

Two resampling schemes, both refitting every resample from the estimate :math:`\hat z` with the one
LM (:meth:`diffship.fit.kernel.Kernel.solve_many`, per-problem data):

* ``"blocks"`` — the residual (recursive) bootstrap of output error with moving blocks
  (Künsch, "The jackknife and the bootstrap for general stationary observations", Ann. Stat. 1989;
  Efron & Tibshirani, *An Introduction to the Bootstrap*, 1993, §8.5). The fitted simulation
  :math:`\hat y_{ik} = \hat y(t_{ik}; \hat\theta, \hat x_{0,i})` stays, the normalised residuals
  :math:`e_{ik\cdot} = (\hat y_{ik} - y_{ik}) / s` of each run are cut into overlapping blocks of
  ``block`` samples (all channels of a sample together: their cross-correlation is kept) and
  redrawn with replacement, and the resampled measurement is
  :math:`y^*_{ik} = \hat y_{ik} - s\,e^*_{ik} = y_{ik} + s\,(e_{ik} - e^*_{ik})`.
  **Measured inputs with noise** (a rudder angle, a thrust record: the level estimated from their
  second differences, :func:`diffship.fit.input_noise.input_noise`, as the covariance's input-noise
  term does) make the output errors of the estimate depend on inputs the refit cannot see; the
  bootstrap then simulates each resample with inputs perturbed by new draws of that noise,
  :math:`\hat y^{(b)} = \hat y(\hat\theta; u + \eta^{(b)})`, and refits against the measured :math:`u`
  (errors in variables, as in the data): :math:`y^*_{ik} = \hat y^{(b)}_{ik} - s\,e^*_{ik}`. Without it
  the intervals covered the truth 67 % of the time with 0.5° rudder noise
  (``benchmarks/bootstrap_coverage.py``); the resampled residuals already hold part of that noise's
  effect, so this errs on the wide side. The default block
  length is twice the largest integrated autocorrelation time of the residual channels,
  :math:`\tau = 1 + 2\sum_{k=1}^{K}\rho_k` summed up to the first negative :math:`\rho_K`
  (coloured output errors — input noise, unmodelled dynamics — need blocks longer than their
  correlation), capped at a quarter of the shortest run.
* ``"runs"`` — whole runs drawn with replacement (each keeps its own estimated initial state);
  needs at least two runs, and says little with few.

Percentile intervals: the 2.5 % and 97.5 % quantiles of the refitted parameters (model units) over the
resamples whose refit converged (Efron & Tibshirani §13.3). They are reported beside the covariance
(Gauss–Newton) intervals :math:`\hat\theta \pm 1.96\,\mathrm{se}`.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx

from ..errors import FitError
from ..models import AbstractModel
from ..params import ParamSpec
from .input_noise import input_noise
from .kernel import PENALTY, Kernel, KernelData

__all__ = ["BootstrapResult", "block_length", "bootstrap_fit", "bootstrap_kernel", "bootstrap_report", "resample"]

_OK = int(jax.tree_util.tree_leaves(optx.RESULTS.successful)[0])


@dataclasses.dataclass(frozen=True, eq=False)
class BootstrapResult:
    """Bootstrap of a fit.

    Attributes:
        names: free parameters.
        estimate: the fit's values (model units).
        samples: refitted values of the converged resamples, ``(n_ok, n_params)``.
        lo, hi: percentile interval bounds (``level``, default 95 %).
        stderr: bootstrap standard deviation of each parameter.
        cov_stderr: the fit's covariance standard errors (``nan`` where not given).
        n: resamples drawn; ``n_ok``: refits that converged (the others are left out and counted).
        method: ``"blocks"`` or ``"runs"``; ``block``: block length in samples (blocks only).
        level: coverage of the intervals; ``seconds``: wall time of the refits (compile included).
    """

    names: tuple[str, ...]
    estimate: np.ndarray
    samples: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    stderr: np.ndarray
    cov_stderr: np.ndarray
    n: int
    n_ok: int
    method: str
    block: int | None
    level: float
    seconds: float

    def contains(self, values) -> np.ndarray:
        """Whether each interval contains ``values`` (a mapping or an array in ``names`` order)."""
        v = np.array([values[n] for n in self.names]) if isinstance(values, dict) else np.asarray(values)
        return (self.lo <= v) & (v <= self.hi)

    def text(self) -> str:
        """The intervals as a text block (percentile beside covariance)."""
        pct = f"{100 * self.level:g} %"
        how = (f"moving blocks of {self.block} samples of each run's residuals" if self.method == "blocks"
               else "runs drawn with replacement")
        lines = [f"bootstrap ({how}): {self.n_ok} of {self.n} refits converged, {self.seconds:.1f} s",
                 f"  {'parameter':<14} {'estimate':>12} {pct + ' percentile':>29} {pct + ' covariance':>29}"]
        z = _z(self.level)
        for i, n in enumerate(self.names):
            cov = (f"[{self.estimate[i] - z * self.cov_stderr[i]:.5g}, {self.estimate[i] + z * self.cov_stderr[i]:.5g}]"
                   if math.isfinite(self.cov_stderr[i]) else "—")
            lines.append(f"  {n:<14} {self.estimate[i]:>12.5g} {f'[{self.lo[i]:.5g}, {self.hi[i]:.5g}]':>29} {cov:>29}")
        if self.n_ok < self.n:
            lines.append(f"  note: {self.n - self.n_ok} refit(s) did not converge and are left out")
        return "\n".join(lines)

    def as_json(self) -> dict:
        """Plain JSON-ready dict."""
        return {"method": self.method, "block_samples": self.block, "n": self.n, "n_converged": self.n_ok,
                "level": self.level, "seconds": self.seconds,
                "params": {n: {"estimate": float(self.estimate[i]), "lo": float(self.lo[i]), "hi": float(self.hi[i]),
                               "stderr": float(self.stderr[i]),
                               "cov_stderr": float(self.cov_stderr[i]) if math.isfinite(self.cov_stderr[i]) else None}
                           for i, n in enumerate(self.names)}}


def _z(level: float) -> float:
    from statistics import NormalDist
    return NormalDist().inv_cdf(0.5 + level / 2)


def block_length(e: np.ndarray, mask: np.ndarray) -> int:
    """Default block length [samples]: twice the largest integrated autocorrelation time of the
    residual channels (module docstring), at least 1, at most a quarter of the shortest run."""
    taus, shortest = [1.0], e.shape[1]
    for i in range(e.shape[0]):
        n = int(mask[i].sum())
        shortest = min(shortest, n)
        for c in range(e.shape[2]):
            x = e[i, :n, c] - e[i, :n, c].mean()
            v = float(x @ x)
            if n < 4 or v == 0:
                continue
            f = np.fft.rfft(x, 2 * n)
            acf = np.fft.irfft(f * np.conj(f))[:n] / v
            neg = np.flatnonzero(acf[1:] < 0)
            k = neg[0] + 1 if neg.size else n
            taus.append(1.0 + 2.0 * float(np.sum(acf[1:k])))
    return int(max(1, min(math.ceil(2 * max(taus)), max(1, shortest // 4))))


def resample(kernel: Kernel, data: KernelData, z_hat, n: int, *, method: str = "blocks", block: int | None = None,
             seed: int = 0, inputs: bool = True) -> tuple[KernelData, np.ndarray, int | None]:
    """``(stacked data with a leading axis n, starts (n, n_z), block)`` of ``n`` resamples around ``z_hat``
    (``inputs``: perturb the simulation's inputs by their estimated measurement noise, module docstring)."""
    rng = np.random.default_rng(seed)
    z_hat = np.asarray(z_hat, dtype=np.float64)
    R, N = data.mask.shape
    C = data.ys.shape[-1]
    if method == "runs":
        if R < 2:
            raise FitError("bootstrap by runs needs at least two runs; use the block bootstrap (method 'blocks')")
        k = kernel.n_theta + kernel.n_extra
        n_d = len(kernel.x0_idx)
        idx = rng.integers(0, R, size=(n, R))
        per_run = ("ts", "us", "ys", "mask", "x0")
        stacked = jax.tree_util.tree_map(lambda a: jnp.broadcast_to(a, (n, *a.shape)), data)
        stacked = stacked.replace(**{f: jnp.asarray(np.asarray(getattr(data, f))[idx]) for f in per_run})
        d = z_hat[k:].reshape(R, n_d) if n_d else np.zeros((R, 0))
        starts = np.stack([np.concatenate([z_hat[:k], d[i].reshape(-1)]) for i in idx])
        return stacked, starts, None
    if method != "blocks":
        raise FitError(f"bootstrap method must be 'blocks' or 'runs', got {method!r}")
    r = np.asarray(kernel.call("residuals", z_hat, data))
    e = kernel.split(r, data)[0].reshape(R, N, C)
    mask = np.asarray(data.mask)
    if np.any(np.abs(e) >= PENALTY):
        raise FitError("bootstrap: the simulation blows up at the estimate; fit first, then bootstrap")
    L = block_length(e, mask) if block is None else int(block)
    if L < 1:
        raise FitError(f"bootstrap block length must be at least 1 sample, got {L}")
    ys = np.asarray(data.ys)
    scales = np.asarray(data.scales)
    stacked = jax.tree_util.tree_map(lambda a: jnp.broadcast_to(a, (n, *a.shape)), data)
    # measured inputs with noise: the simulation of each resample runs on u + η*, the refit sees u
    base = np.repeat(e[None], n, axis=0)
    if inputs:
        scale, corr = input_noise(np.asarray(data.us), mask)
        if np.any(scale[mask] > 0):
            chol = np.linalg.cholesky(corr + 1e-12 * np.eye(corr.shape[0]))
            eta = (rng.standard_normal((n, *scale.shape)) @ chol.T) * scale[None]
            perturbed = stacked.replace(us=jnp.asarray(np.asarray(data.us)[None] + eta))
            sim = jax.jit(jax.vmap(kernel.residuals, in_axes=(None, 0)))(jnp.asarray(z_hat), perturbed)
            base = np.asarray(jax.vmap(lambda r: kernel.split(r, data)[0])(sim)).reshape(n, R, N, C)
    out = np.repeat(ys[None], n, axis=0)
    for i in range(R):
        m = int(mask[i].sum())
        if not np.all(mask[i, :m]):
            raise FitError(f"bootstrap: run {i} has masked samples inside it; blocks need contiguous samples")
        Li = min(L, m)
        nb = -(-m // Li)
        for b in range(n):
            s0 = rng.integers(0, m - Li + 1, size=nb)
            idx = (s0[:, None] + np.arange(Li)[None]).reshape(-1)[:m]
            out[b, i, :m] = ys[i, :m] + scales * (base[b, i, :m] - e[i, idx])
    stacked = stacked.replace(ys=jnp.asarray(out))
    return stacked, np.tile(z_hat, (n, 1)), L


def bootstrap_kernel(kernel: Kernel, data: KernelData, z_hat, n: int, *, method: str = "blocks",
                     block: int | None = None, seed: int = 0, level: float = 0.95, cov_stderr=None,
                     workers: int | None = None, solve: str = "auto", **lm) -> BootstrapResult:
    """Bootstrap of the output-error fit ``z_hat`` of ``(kernel, data)``: ``n`` resamples refitted in
    one :meth:`Kernel.solve_many` call (``lm``: its tolerances, ``max_steps``, ``rtol``, ``atol``, ...)."""
    import time
    if n < 2:
        raise FitError(f"--bootstrap needs at least 2 resamples, got {n}")
    t0 = time.perf_counter()
    stacked, starts, L = resample(kernel, data, z_hat, n, method=method, block=block, seed=seed)
    outs = kernel.solve_many(starts, stacked, per_problem=True, workers=workers, method=solve, **lm)
    k = kernel.n_theta
    ok = [o for o in outs if o[1] == optx.RESULTS.successful and not np.any(np.abs(np.asarray(o[3])) >= PENALTY)]
    theta = np.array([np.asarray(kernel.spec.from_z(jnp.asarray(np.asarray(o[0])[:k]))) for o in ok]).reshape(-1, k)
    est = np.asarray(kernel.spec.from_z(jnp.asarray(np.asarray(z_hat)[:k])))
    a = 100 * (1 - level) / 2
    lo, hi = (np.percentile(theta, [a, 100 - a], axis=0) if len(ok) >= 2 else (np.full(k, np.nan),) * 2)
    sd = theta.std(axis=0, ddof=1) if len(ok) >= 2 else np.full(k, np.nan)
    cse = np.full(k, np.nan) if cov_stderr is None else np.asarray(cov_stderr, dtype=float)
    return BootstrapResult(names=tuple(kernel.spec.free_names), estimate=est, samples=theta, lo=lo, hi=hi, stderr=sd,
                           cov_stderr=cse, n=n, n_ok=len(ok), method=method, block=L, level=level,
                           seconds=time.perf_counter() - t0)


def bootstrap_fit(result, runs: Sequence, *, spec: ParamSpec | None = None, options=None, n: int,
                  method: str = "blocks",
                  block: int | None = None, seed: int = 0, level: float = 0.95, workers: int | None = None
                  ) -> BootstrapResult:
    """Bootstrap of an output-error :class:`~diffship.fit.result.FitResult` on its training ``runs``.

    The problem is rebuilt by the estimator that made the fit (``options``, an
    :class:`~diffship.fit.output_error.OutputError`: its ``prepare`` gives the same kernel, channel
    scales, priors and initial-state prior rows; its compiled programs are the fit's), at the fit's
    channel scales, with the fit's estimated initial states as offsets from the measured ones, so
    that the residuals at the estimate are the fit's. ``spec`` and ``options`` default to the ones
    the driver recorded in the result (:attr:`FitResult.spec`, :attr:`FitResult.estimator`)."""
    import dataclasses

    from .driver import fit_priors

    if result.method != "output_error":
        raise FitError(f"bootstrap: needs an output-error fit, got {result.method}")
    spec = result.spec if spec is None else spec
    options = result.estimator if options is None else options
    if spec is None or options is None:
        raise FitError("bootstrap: give spec= and options= (this result does not record how it was fitted)")
    model: AbstractModel = result.model
    spec = spec.with_values({k: result.params[k] for k in spec.free_names})
    est = tuple(result.info.get("estimate_x0", options.estimate_x0))
    changes = {"estimate_x0": est, "channel_scales": dict(result.channel_scales)}
    if hasattr(options, "ee_start"):
        changes["ee_start"] = False  # no equation-error start needed: the refits start at the estimate
    options = dataclasses.replace(options, **changes)
    priors, _ = fit_priors(model, spec, options)
    problem = options.prepare(model, runs, spec, list(result.channels), priors, lambda _s: None)
    kernel, data, batch = problem.state["kernel"], problem.state["data"], problem.state["batch"]
    d = np.zeros((len(runs), len(kernel.x0_idx)))
    if kernel.x0_idx and result.initial_states:
        x0_fit = np.stack([np.asarray(x) for x in result.initial_states])
        d = (x0_fit - np.asarray(batch.x0))[:, list(kernel.x0_idx)] / np.asarray(data.x0_scale)
    z_hat = np.concatenate([spec.to_z(), d.reshape(-1)])
    lm = dict(options.lm)
    if jax.default_backend() == "cpu":
        # the refits run the fit's own compiled one-fit program (threads): same keywords, no new compile
        lm["jacobian"] = True
    cse = [result.stderr.get(n_, math.nan) for n_ in spec.free_names]
    return bootstrap_kernel(kernel, data, z_hat, n, method=method, block=block, seed=seed, level=level,
                            cov_stderr=cse, workers=workers, **lm)


def bootstrap_report(result, runs: Sequence, n: int, method: str = "blocks", say=lambda s: None, *,
                     spec: ParamSpec | None = None, options=None) -> tuple[str, dict | None]:
    """``--bootstrap N`` for a command line: the report block and the JSON entry (``None`` when skipped:
    a fit that did not converge is not resampled, and the block says so)."""
    if not result.converged:
        return "bootstrap: skipped (the output-error fit did not converge)", None
    say(f"bootstrap: refitting {n} resamples ({method})...")
    boot = bootstrap_fit(result, runs, spec=spec, options=options, n=n, method=method)
    say(f"bootstrap: {boot.n_ok} of {boot.n} refits converged in {boot.seconds:.1f} s")
    return boot.text(), boot.as_json()

