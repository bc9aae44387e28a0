r"""Conditioning chosen from the data and the model: what a fit does by default, said in one line each.

The fit's answer does not depend on the sample rate (the likelihood counts effective samples, not samples:
:func:`~diffship.fit.weights.concentrated_cost`), so how densely the runs are sampled only decides how long a
fit takes. Runs logged far faster than the model's dynamics are thinned before the fit:

* **the model's time scale** (:func:`fastest_time_constant`): the eigenvalues of the vector field's Jacobian
  at the runs' operating point (their mean first state and mean inputs, the model at its start values);
  :math:`T = 1/\max|\lambda|`;
* **the rate** (:func:`thinning`): the runs are averaged over blocks of ``k`` samples
  (:func:`block_average`: the noise of the average falls as the block grows, so a white-noise channel keeps
  its information about the slow dynamics), ``k`` the factor that leaves nearest :data:`SAMPLES_PER_T` samples in
  ``T`` (never fewer than :data:`MIN_SAMPLES_PER_T`), and only where ``k ≥`` :data:`MIN_FACTOR` (a smaller gain is not worth a second look at the data).
  The HSVA KVLCC2 zigzags (20 Hz) are fitted at 5 Hz: the MMG's fastest mode there is 2.0 s; a USV at 10 Hz
  (fastest mode 2.3 s) is fitted as logged. Only a model whose start values are a real vessel's (its reference
  set on its reference vessel) tells the time scale before the fit; other models are fitted at the logged rate.

``--resample DT`` overrides the choice; the fit's report prints it.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

import jax
import jax.numpy as jnp
import numpy as np

from ..data import Run
from ..hold import held_means
from ..models import AbstractModel
from ..simulate import initial_state, model_inputs

__all__ = ["MIN_FACTOR", "MIN_SAMPLES_PER_T", "SAMPLES_PER_T", "Thinning", "block_average", "fastest_time_constant", "thinning"]

#: Samples the thinned runs keep within the model's fastest time constant (the nearest factor; never fewer than
#: MIN_SAMPLES_PER_T).
SAMPLES_PER_T = 10
MIN_SAMPLES_PER_T = 8
#: Runs are thinned only by a factor of at least this.
MIN_FACTOR = 4


def fastest_time_constant(model: AbstractModel, runs: Sequence[Run]) -> float:
    """The model's fastest time constant [s] at the runs' operating point (module docstring); ``inf`` where
    the linearisation has no decaying or oscillating mode (or cannot be formed)."""
    try:
        x = np.mean([np.asarray(initial_state(model, r), dtype=np.float64) for r in runs], axis=0)
        u = np.mean(np.concatenate([model_inputs(model, r) for r in runs]), axis=0)
        J = jax.jacfwd(lambda xx: model.vector_field(0.0, xx, jnp.asarray(u)))(jnp.asarray(x))
        lam = np.abs(np.linalg.eigvals(np.asarray(J)))
    except Exception:  # a model without a linearisation here: no thinning
        return math.inf
    lam = lam[np.isfinite(lam) & (lam > 1e-9)]
    return float(1.0 / lam.max()) if lam.size else math.inf


def block_average(run: Run, k: int, inputs: Sequence[str] = (), hold: str = "linear") -> Run:
    """``run`` averaged over consecutive blocks of ``k`` samples (time: each block's mean; headings
    unwrapped first); a last incomplete block is dropped. The run given is not changed.

    ``inputs`` held between samples (``hold="zero"``: a digital command; :mod:`diffship.integrators`) are averaged
    over the interval each averaged sample holds them, from its time to the next one's, not over its block: a
    block's mean stands at the block's mean time, and held from there it reaches the model (k − 1)/2 samples late
    (measured: a USV's surge added mass 15–22 % high, 20 Hz commands averaged to 5 Hz). Under the linear hold the
    block's mean is the signal's value at the block's mean time, which is what that hold reads."""
    n = (run.n // k) * k
    if k <= 1 or n < 2 * k:
        return run
    time = np.asarray(run.time, dtype=np.float64)
    t = time[:n].reshape(-1, k).mean(axis=1)
    held = set(inputs) if hold == "zero" else set()
    t_end = float(time[-1] + np.median(np.diff(time)))
    chans = {}
    for c, a in run.channels.items():
        a = np.asarray(a, dtype=np.float64)
        if c in held:
            chans[c] = held_means(time, a, t, t_end)
            continue
        a = a[:n]
        if c in ("psi", "phi", "theta"):
            a = np.unwrap(a)
        chans[c] = a.reshape(-1, k).mean(axis=1)
    return Run(run.name, t, chans, {**run.metadata, "block_average": int(k)}, check_units=run.check_units)


@dataclasses.dataclass(frozen=True)
class Thinning:
    """The thinning chosen for a fit: ``factor`` (1: none), the model's ``time_constant`` [s], the runs'
    sample interval ``dt`` [s] and the sentence the report prints."""

    factor: int
    time_constant: float
    dt: float
    text: str

    def apply(self, runs: Sequence[Run], inputs: Sequence[str] = (), hold: str = "linear") -> list[Run]:
        """The runs averaged over blocks of ``factor`` samples (:func:`block_average`; ``inputs`` and ``hold``
        as there: the model's inputs and the integrator's input hold)."""
        return [block_average(r, self.factor, inputs, hold) for r in runs] if self.factor > 1 else list(runs)


def thinning(model: AbstractModel, runs: Sequence[Run], known: bool = True) -> Thinning:
    """The block-averaging factor for ``runs`` (module docstring) and the line that says why. ``known``: the
    model's start values are a real vessel's (its reference set on its reference vessel); a generic start (a
    Nomoto model's default time constant) says nothing of the runs' time scale, and they are fitted as logged."""
    dt = float(np.median(np.concatenate([np.diff(np.asarray(r.time, dtype=np.float64)) for r in runs])))
    if not known:
        return Thinning(1, math.nan, dt, f"conditioning: runs fitted at their own rate ({1 / dt:.3g} Hz; the model's "
                                         "start values are not a known vessel's, so they do not tell its time scale)")
    T = fastest_time_constant(model, runs)
    # the factor nearest to ten samples in T, with never fewer than MIN_SAMPLES_PER_T
    k = min(int(round(T / SAMPLES_PER_T / dt)), int(math.floor(T / MIN_SAMPLES_PER_T / dt))) if math.isfinite(T) else 1
    if k >= MIN_FACTOR:
        return Thinning(k, T, dt, f"conditioning: runs averaged over blocks of {k} samples ({1 / dt:.3g} Hz → "
                                  f"{1 / (k * dt):.3g} Hz): the model's fastest time constant at the runs' operating "
                                  f"point, {T:.2g} s, spans {T / (k * dt):.0f} samples (--resample DT to choose)")
    why = (f"the model's fastest time constant, {T:.2g} s, spans {T / dt:.0f} samples" if math.isfinite(T)
           else "the model has no decaying mode at the runs' operating point")
    return Thinning(1, T, dt, f"conditioning: runs fitted at their own rate ({1 / dt:.3g} Hz; {why})")
