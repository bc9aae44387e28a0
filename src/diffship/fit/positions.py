r"""Measured positions in the fit: added where a Hausman test finds they agree with the other channels.

GNSS positions carry information the heading and velocities do not: on the independent USV truth of
``benchmarks/fossen3_crlb.py`` (0.5 m noise, two runs × 300 s) Xu's Cramér–Rao bound is 2.9 % with them and 3.8 %
without. Where the model misses, though, a position integrates the miss into a drift that grows with time and decides
the fit (the MMG on the HSVA KVLCC2 zigzags: training y0 fit −440 %, a held-out zigzag failed). So the output-error
fit (:class:`~diffship.fit.OutputError`, ``positions="test"``, the default) fits the channels without positions
first (:data:`~diffship.fit.problem.NOT_FITTED_BY_DEFAULT`), then, where every run measures positions the model
predicts, refits from that optimum with them, and keeps the refit only where the two agree.

**The test** (Hausman 1978). Let :math:`\hat\theta_d` be the fit without positions, :math:`\hat\theta_p` the fit with
them, :math:`V_d, V_p` their covariances. Where the model is right both are consistent and :math:`\hat\theta_p` is
efficient (it uses more of the same likelihood), so :math:`\operatorname{Var}(\hat\theta_d-\hat\theta_p) = V_d - V_p`
and

.. math:: H = (\hat\theta_d-\hat\theta_p)^\top (V_d - V_p)^{+} (\hat\theta_d-\hat\theta_p) \sim \chi^2_k,

with :math:`k` the rank of the positive part of :math:`V_d - V_p` (eigenvalues above :data:`EIG_RTOL` of the
largest). Where the model misses, the positions pull the estimate along their drift and :math:`H` is large. The
refit is kept when :math:`P(\chi^2_k > H) \ge` :data:`ALPHA` **and** the positions make no combination of the
coefficients less certain: the largest generalised eigenvalue :math:`\mu` of :math:`V_p v = \mu V_d v` (the widest
ratio of variances, with over without) is at most :data:`MAX_WIDENING`. Where the model is right, more data cannot
widen an interval (:math:`\mu \le 1` up to the covariance estimates' own scatter); where the positions drift away
from the model, the fit's noise weighting (:func:`~diffship.fit.weights.concentrated_cost`) reads the drift as noise
and down-weights them: the estimate hardly moves (H small) but their coloured residuals widen the intervals, so
fitting them would cost precision for nothing.

**A screen before the refit.** Where the fit misses the channels it fits by far more than their noise, a position —
which integrates those misses — will not agree, and the refit (as long as the fit itself) is skipped. Each fitted
channel's residual RMS is compared with its sample-to-sample noise, :math:`\hat\sigma_c = 1.4826\,\mathrm{MAD}
(\Delta^2 y_c)/\sqrt6` per run (:func:`diffship.initial.noise_floor`; white noise of variance σ² gives second differences of variance 6σ²; a track smooth at the
sample rate adds little, and the median ignores the rare steps of a command); the refit runs only where every ratio is
at most :data:`SCREEN`. Measured: 0.96–1.10 on the independent USV runs and the USV of :mod:`diffship.synthetic`
(the model right), 34–8750 for the MMG on the HSVA KVLCC2 zigzags (5 and 20 Hz). A sensor whose output is smoothed
reads as less noisy than it is, so the screen then keeps the positions out: the fit of the other channels, as with
``positions="off"``.

Measured (:mod:`benchmarks.fossen3_coverage`, and the fit's own tests): the independent USV truth, 2 runs × 300 s,
seeds 0–5, p = 0.09, 0.78, 0.08, 0.16, 0.93, 0.49 and μ = 0.95–0.98 (kept); the USV of
:func:`diffship.synthetic.usv_runs`, 2 runs × 60 s, μ = 1.05 without a drift, 1.25 with a 0.02–0.05 m/s drift in
the GNSS track alone, 2.1 with 0.15 m/s (p ≈ 1: left out by μ); the HSVA KVLCC2 zigzags with the MMG (left out by
the screen), refitted anyway: H = 117 on 14 degrees of freedom, p = 3e-18, μ = 33; the USV of
:mod:`diffship.synthetic` in a water current (three runs × 240 s, the current unmodelled): none, kept (p = 0.82,
μ = 0.95); 0.05 m/s, left out by μ = 19.9 (p = 1); 0.25 m/s, left out by the screen (u misfit 3.7).

Reference: J. A. Hausman, "Specification tests in econometrics", *Econometrica* 46(6), 1251–1271, 1978.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence

import numpy as np
from numpy.typing import ArrayLike
from scipy import special

from ..data import Run
from ..initial import pooled_noise_floor

__all__ = ["ALPHA", "EIG_RTOL", "MAX_WIDENING", "SCREEN", "PositionsTest", "hausman", "misfit"]

#: Significance level of the test: the positions are added unless the two fits disagree at this level.
ALPHA = 0.05
#: The positions may widen no combination of the coefficients' variance by more than this factor (module docstring).
MAX_WIDENING = 1.15
#: The refit runs only where every fitted channel's residual RMS is at most this many times its sample-to-sample noise.
SCREEN = 3.0
#: Eigenvalues of V_d − V_p above this fraction of the largest count as the test's positive part.
EIG_RTOL = 1e-8


@dataclasses.dataclass(frozen=True)
class PositionsTest:
    """The outcome of :func:`hausman` for one pair of fits.

    Attributes:
        channels: the position channels tested (``("x0", "y0")``).
        kept: whether the fit with positions is the answer.
        reason: why not, where it is not (the screen, the refit failed, a covariance is infinite, the test rejects).
        statistic: H (module docstring); ``nan`` where it was not formed.
        dof: k, the rank of the positive part of V_d − V_p.
        p_value: P(χ²_k > H).
        negative: how many directions the fit with positions is less certain in (negative eigenvalues).
        worst: the coefficient that moved most, in standard errors of the difference, and by how many.
        widening: μ, the largest ratio of a combination's variance with the positions over without (module docstring).
    """

    channels: tuple[str, ...]
    kept: bool
    reason: str = ""
    statistic: float = math.nan
    dof: int = 0
    p_value: float = math.nan
    negative: int = 0
    worst: tuple[str, float] | None = None
    widening: float = math.nan

    def describe(self) -> str:
        chans = ", ".join(self.channels)
        if not math.isfinite(self.statistic):
            return f"positions ({chans}) not fitted: {self.reason}"
        test = (f"Hausman H = {self.statistic:.1f} on {self.dof} dof, p = {self.p_value:.2g}; widest variance ratio "
                f"{self.widening:.2f}")
        moved = f"; {self.worst[0]} moved {self.worst[1]:.1f} se" if self.worst is not None else ""
        if self.kept:
            return (f"positions ({chans}) fitted: the fit with them agrees with the fit without them ({test}{moved}); "
                    f"--positions off leaves them out")
        return (f"positions ({chans}) not fitted: {self.reason or 'the fit with them disagrees with the fit without'} "
                f"({test}{moved}: where the model misses, a position's drift decides the fit); --channels with them "
                f"fits them anyway; what the model misses: python -m diffship.diagnose, or, for inputs logged as "
                f"commands held between samples, --input-hold zero")

    def as_json(self) -> dict:
        return {"channels": list(self.channels), "statistic": self.statistic, "dof": self.dof,
                "p_value": self.p_value, "negative_directions": self.negative, "widening": self.widening,
                "kept": self.kept, "reason": self.reason,
                "worst": None if self.worst is None else {"param": self.worst[0], "se": self.worst[1]}}


def hausman(names: Sequence[str], theta_d: ArrayLike, cov_d: ArrayLike, theta_p: ArrayLike, cov_p: ArrayLike,
            channels: Sequence[str] = ("x0", "y0"), alpha: float = ALPHA,
            max_widening: float = MAX_WIDENING) -> PositionsTest:
    """The Hausman test of the fit with positions (``theta_p``, ``cov_p``) against the fit without (module docstring).

    Args:
        names: the free parameters, in the order of both covariances.
        theta_d: the estimate without positions (model units).
        cov_d: its covariance.
        theta_p: the estimate with positions.
        cov_p: its covariance.
        channels: the position channels, for the report.
        alpha: the significance level (default :data:`ALPHA`).
        max_widening: the largest variance ratio allowed (default :data:`MAX_WIDENING`).
    """
    d = np.asarray(theta_p, dtype=np.float64) - np.asarray(theta_d, dtype=np.float64)
    V = np.asarray(cov_d, dtype=np.float64) - np.asarray(cov_p, dtype=np.float64)
    chans = tuple(channels)
    if not (np.all(np.isfinite(d)) and np.all(np.isfinite(V))):
        return PositionsTest(chans, False, "a standard error of one of the two fits is infinite (not identifiable)")
    mu = _widening(np.asarray(cov_d, dtype=np.float64), np.asarray(cov_p, dtype=np.float64))
    w, U = np.linalg.eigh(0.5 * (V + V.T))
    top = float(np.max(np.abs(w))) if w.size else 0.0
    pos = w > EIG_RTOL * top
    neg = int(np.sum(w < -EIG_RTOL * top))
    if top == 0.0 or not pos.any():
        return PositionsTest(chans, False, negative=neg, widening=mu, reason=(
            f"with them no combination of the coefficients is more certain (widest variance ratio {mu:.2f})"))
    q = U[:, pos].T @ d
    H = float(np.sum(q ** 2 / w[pos]))
    k = int(pos.sum())
    p = float(special.chdtrc(k, H))  # P(χ²_k > H)
    sd = np.sqrt(np.clip(np.diag(V), 0.0, None))
    with np.errstate(divide="ignore", invalid="ignore"):
        zs = np.where(sd > 0, np.abs(d) / sd, 0.0)
    i = int(np.argmax(zs))
    worst = (str(names[i]), float(zs[i])) if len(names) else None
    if p < alpha:
        reason = f"the fit with them disagrees with the fit without at the {alpha:g} level"
    elif not mu <= max_widening:
        reason = (f"with them a combination of the coefficients is {mu:.2f} times less certain (variance): their "
                  f"residuals are not noise about the model's track")
    else:
        reason = ""
    return PositionsTest(chans, not reason, reason, statistic=H, dof=k, p_value=p, negative=neg, worst=worst,
                         widening=mu)


def _widening(cov_d: np.ndarray, cov_p: np.ndarray) -> float:
    """The largest μ of V_p v = μ V_d v: how many times less certain the most widened combination is with the
    positions (V_d whitened by its eigen-decomposition; directions V_d does not resolve are left out)."""
    w, U = np.linalg.eigh(0.5 * (cov_d + cov_d.T))
    keep = w > EIG_RTOL * max(float(w.max()), 0.0)
    if not keep.any():
        return math.nan
    W = U[:, keep] / np.sqrt(w[keep])
    return float(np.linalg.eigvalsh(W.T @ (0.5 * (cov_p + cov_p.T)) @ W).max())


def misfit(runs: Sequence[Run], residual_rms: Mapping[str, float], angles: Sequence[str] = ()) -> dict[str, float]:
    """Each fitted channel's residual RMS over its sample-to-sample noise (module docstring, "A screen"): about 1
    where the model follows the channel to its noise. Angles (``angles``) are unwrapped first; a channel whose noise
    reads as zero (constant, or quantised coarser than its changes) is left out."""
    out = {}
    for c, rms in residual_rms.items():
        sigma = pooled_noise_floor([np.unwrap(np.asarray(r[c], dtype=np.float64)) if c in angles else r[c]
                                    for r in runs])
        if sigma > 0 and math.isfinite(rms):
            out[c] = float(rms) / sigma
    return out
