r"""Parameter covariance from a least-squares Jacobian (the one place it is computed).

At the optimum of :math:`\tfrac12\lVert r(z)\rVert^2` with ``m`` residuals and ``p`` unknowns the
estimate's error is, to first order, :math:`\hat z - z = -H^{-1}J^\top r` with
:math:`H = J^\top J`. Its covariance is the **sandwich**

.. math::
    \mathrm{Cov}(\hat z) = H^{-1}\,\Omega\,H^{-1},\qquad \Omega = \mathrm{Cov}(J^\top r).

Three estimates of Ω (``kind``):

* ``"white"`` — residuals independent with one variance: :math:`\Omega = \hat\sigma^2 H`,
  :math:`\hat\sigma^2 = r^\top r/(m-p)`, hence the classical :math:`\hat\sigma^2 (J^\top J)^{-1}`.
  Honest only when the residuals are white (sensor noise alone).
* ``"hac"`` — heteroskedasticity and autocorrelation consistent (Newey & West 1987): per run,
  the score series :math:`g_k = \sum_c J_{kc}^\top r_{kc}` (one row per sample, channels summed,
  so correlations between channels at equal times are kept) is summed over consecutive blocks of ``b``
  samples, ``b`` the smallest (growing by half, at least 20 blocks a run) whose block sums have a lag-1
  autocorrelation of at most 0.8 (:func:`aggregated`: the sum of the scores, hence the long-run covariance,
  is unchanged, and the same experiment logged at 10 or 50 Hz gives the same standard errors; without it an
  AR(1) of φ = 0.99 at 50 Hz lies beyond the prewhitening cap and the variance came out a seventh of the
  truth), then prewhitened with a per-component
  AR(1) filter (Andrews & Monahan 1992; coefficients capped at 0.97), its long-run covariance is
  estimated with the Bartlett kernel

  .. math::
      \hat\Omega_i = \hat\Gamma_0 + \sum_{l=1}^{L_i}\Big(1-\frac{l}{L_i+1}\Big)(\hat\Gamma_l + \hat\Gamma_l^\top),
      \qquad \hat\Gamma_l = \sum_k g^*_k g^{*\top}_{k+l},

  with the bandwidth :math:`L_i = 1.1447\,(\hat\alpha(1)\,n_i)^{1/3}` chosen from the data by
  Andrews' (1991) AR(1) plug-in rule, recoloured, and summed over runs (runs independent).
  Measured inputs (rudder-angle and thrust noise) and unmodelled disturbances make
  output-error residuals coloured: then this is the honest one.
* ``"block"`` — a moving-block bootstrap of the same (block-summed) score series (block length ``2 L_i``,
  ``n_boot`` resamples), :math:`\hat z^{*}-\hat z = -H^{-1}\sum g^{*}`: the bootstrap
  counterpart of ``"hac"`` at linearised cost (no refits), for comparison.
* ``"auto"`` — ``"hac"`` where the residuals are not white (:func:`whiteness`), else ``"white"``.

**Measured inputs** (errors in variables): noise on the inputs the fit simulates with moves
the estimate through a low-frequency component of the residuals that the fit itself absorbs,
so no estimate from the fitted residuals sees it. Given its contribution
:math:`\Omega_u = A^\top\Sigma_u A` (``input_meat``; :mod:`diffship.fit.input_noise`), it is
added to the middle of the sandwich: :math:`H^{-1}(\Omega + \Omega_u)H^{-1}`.

Inverse and rank: :math:`H^{-1}` comes from the SVD :math:`J = U\Sigma V^\top` as
:math:`V\Sigma^{-2}V^\top`. Where ``J`` is (numerically) rank deficient the inverse does not
exist: the directions with singular values below ``rtol·σ_max`` are dropped and every unknown
that takes part in them gets an **infinite** variance — never a pseudo-inverse's zero, which
would claim perfect knowledge of a parameter the data say nothing about. Standard errors of the
model parameters follow by the delta method (:meth:`diffship.params.ParamSpec.dtheta_dz`).

**Whiteness** (:func:`whiteness`): per run and channel the lag-1 autocorrelation of the
residuals and the Ljung–Box statistic :math:`Q = n(n+2)\sum_{l=1}^{h}\hat\rho_l^2/(n-l)`
(χ²ₕ under whiteness; Ljung & Box 1978); the residuals count as white when no p-value falls
below ``alpha`` after a Bonferroni correction over runs and channels.

References:
    W. K. Newey, K. D. West, "A simple, positive semi-definite, heteroskedasticity and
    autocorrelation consistent covariance matrix", Econometrica 55, 1987.
    D. W. K. Andrews, "Heteroskedasticity and autocorrelation consistent covariance matrix
    estimation", Econometrica 59, 1991.
    D. W. K. Andrews, J. C. Monahan, "An improved heteroskedasticity and autocorrelation
    consistent covariance matrix estimator", Econometrica 60, 1992.
    G. M. Ljung, G. E. P. Box, "On a measure of lack of fit in time series models", Biometrika 65, 1978.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from jaxtyping import Bool, Float

from ..errors import FitError

__all__ = ["KINDS", "Covariance", "Whiteness", "aggregated", "covariance", "predictability", "relabelled", "whiteness"]

#: Accepted values of ``kind``.
KINDS = ("white", "hac", "block", "auto")

#: Cap of the AR(1) prewhitening coefficients (Andrews & Monahan 1992).
_RHO_CAP = 0.97
#: The score is summed over blocks until their lag-1 autocorrelation is at most this (module docstring).
_RHO_AGGREGATE = 0.8
#: ... keeping at least this many blocks per run.
MIN_BLOCKS = 20


@dataclasses.dataclass(frozen=True, eq=False)
class Whiteness:
    """Residual whiteness per run and channel.

    Attributes:
        lag1: lag-1 autocorrelation, ``(R, C)``.
        ljung_box_p: Ljung–Box p-value over ``lags`` lags, ``(R, C)``.
        lags: number of lags in the Ljung–Box statistic.
        alpha: family-wise level of the test (Bonferroni over the R·C series).
        runs, channels: labels of the rows and columns (may be empty).
    """

    lag1: np.ndarray
    ljung_box_p: np.ndarray
    lags: int
    alpha: float = 0.01
    runs: tuple[str, ...] = ()
    channels: tuple[str, ...] = ()

    @property
    def white(self) -> bool:
        """No series rejects whiteness at ``alpha`` (Bonferroni-corrected)."""
        p = self.ljung_box_p[np.isfinite(self.ljung_box_p)]
        return bool(p.size == 0 or np.min(p) >= self.alpha / max(p.size, 1))

    def describe(self) -> str:
        """One line: verdict, largest lag-1 autocorrelation and where."""
        if self.lag1.size == 0:
            return "residual whiteness: no residuals"
        i, j = np.unravel_index(int(np.nanargmax(np.abs(self.lag1))), self.lag1.shape)
        where = ""
        if self.runs and self.channels:
            where = f" (run {self.runs[i]}, channel {self.channels[j]})"
        verdict = "white" if self.white else "coloured (not white)"
        return (f"residuals {verdict}: lag-1 autocorrelation median {np.nanmedian(self.lag1):.2f}, "
                f"largest {self.lag1[i, j]:.2f}{where}; smallest Ljung–Box p ({self.lags} lags) "
                f"{np.nanmin(self.ljung_box_p):.2g}")

    def as_dict(self) -> dict:
        """JSON-ready: verdict, per-run-and-channel lag-1 autocorrelation and p-values."""
        def table(a):
            if self.runs and self.channels:
                return {r: {c: float(a[i, j]) for j, c in enumerate(self.channels)} for i, r in enumerate(self.runs)}
            return a.tolist()

        return {"white": self.white, "lag1": table(self.lag1), "ljung_box_p": table(self.ljung_box_p),
                "lags": self.lags, "alpha": self.alpha}


@dataclasses.dataclass(frozen=True, eq=False)
class Covariance:
    """Covariance of the unknowns and how it was obtained.

    Attributes:
        matrix: ``(p, p)``; rows/columns of unidentifiable unknowns hold ``inf`` on the diagonal.
        residual_variance: :math:`\\hat\\sigma^2`.
        singular_values: of ``J`` (descending).
        rank: number of singular values kept.
        unidentifiable: indices of the unknowns in the dropped directions.
        kind: the estimate used (``"white"``, ``"hac"`` or ``"block"``; never ``"auto"``).
        bandwidth: per-run Bartlett bandwidth [samples] (``"hac"``/``"block"``; empty otherwise).
        whiteness: residual whiteness, where the residuals' run/channel layout was given.
        input_noise: ``{input: σ̂}`` of the measured inputs whose noise was propagated (empty: none).
    """

    matrix: np.ndarray
    residual_variance: float
    singular_values: np.ndarray
    rank: int
    unidentifiable: tuple[int, ...]
    kind: str = "white"
    bandwidth: tuple[float, ...] = ()
    whiteness: Whiteness | None = None
    input_noise: dict[str, float] = dataclasses.field(default_factory=dict)

    @property
    def full_rank(self) -> bool:
        return not self.unidentifiable

    def describe(self) -> str:
        """One line for reports: which covariance, why, with what bandwidth."""
        how = {"white": "σ̂²(JᵀJ)⁻¹ (white residuals)",
               "hac": "sandwich, Newey–West HAC per run (Bartlett, AR(1)-prewhitened score)",
               "block": "moving-block bootstrap of the score, linearised"}[self.kind]
        bw = (f", bandwidth {min(self.bandwidth):.0f}–{max(self.bandwidth):.0f} samples"
              if self.bandwidth else "")
        eiv = ""
        if self.input_noise:
            eiv = (" + measured-input noise propagated (errors in variables; σ̂ "
                   + ", ".join(f"{k} {v:.3g}" for k, v in self.input_noise.items()) + ")")
        return f"covariance: {how}{bw}{eiv}" + (f"; {self.whiteness.describe()}" if self.whiteness is not None else "")

    def info(self) -> dict:
        """JSON-ready summary for ``FitResult.info``."""
        out = {"covariance": self.kind + ("+inputs" if self.input_noise else ""),
               "covariance_bandwidth": list(self.bandwidth), "input_noise": dict(self.input_noise)}
        if self.whiteness is not None:
            out["whiteness"] = self.whiteness.as_dict()
        return out


# -- whiteness -----------------------------------------------------------------------------------
def _acf(x: np.ndarray, lags: int) -> np.ndarray:
    x = x - x.mean()
    d = float(x @ x)
    if d <= 0:
        return np.zeros(lags)
    return np.array([float(x[:-l] @ x[l:]) / d for l in range(1, lags + 1)])


def whiteness(r: Float[np.ndarray, " m"], mask: Bool[np.ndarray, "R N"], n_channels: int, *, lags: int | None = None,
              alpha: float = 0.01, runs: tuple[str, ...] = (), channels: tuple[str, ...] = ()) -> Whiteness:
    """Lag-1 autocorrelation and Ljung–Box p-value of residuals ``r`` laid out as
    ``(run, sample, channel)`` (``mask`` marks the real samples of each run)."""
    mask = np.asarray(mask, dtype=bool)
    e = np.asarray(r, dtype=np.float64).reshape(mask.shape + (n_channels,))
    R = mask.shape[0]
    n_min = int(mask.sum(1).min()) if R else 0
    h = int(lags) if lags is not None else max(1, min(20, n_min // 5))
    lag1 = np.full((R, n_channels), np.nan)
    p = np.full((R, n_channels), np.nan)
    for i in range(R):
        for c in range(n_channels):
            x = e[i, mask[i], c]
            n = x.size
            if n < h + 3 or not np.any(x != x[0]):
                continue
            rho = _acf(x, h)
            lag1[i, c] = rho[0]
            q = n * (n + 2) * float(np.sum(rho**2 / (n - np.arange(1, h + 1))))
            from scipy.special import chdtrc  # χ² survival function; scipy.stats would cost 0.4 s per process

            p[i, c] = float(chdtrc(h, q))
    return Whiteness(lag1, p, h, alpha, tuple(runs), tuple(channels))


def predictability(r: Float[np.ndarray, " m"], mask: Bool[np.ndarray, "R N"], n_channels: int,
                   order: int = 4) -> float:
    r"""Share of the residuals' variance that their own past predicts: :math:`1 - \sum e_k^2 / \sum (x_k-\bar x)^2`
    pooled over runs and channels, with :math:`e_k` the error of an AR(``order``) model of each run's channel
    :math:`x` fitted by least squares, :math:`x_k \approx c + \sum_{l=1}^{p} a_l x_{k-l}`. About ``order``/N for white
    residuals; near 1 when they carry an oscillation or a drift the model's noise description misses (a
    prediction-error fit whose measurement noise holds the disturbance). NaN where no run is long enough."""
    mask = np.asarray(mask, dtype=bool)
    e = np.asarray(r, dtype=np.float64).reshape(mask.shape + (n_channels,))
    num = den = 0.0
    for i in range(mask.shape[0]):
        for c in range(n_channels):
            x = e[i, mask[i], c]
            if x.size < 4 * (order + 1):
                continue
            X = np.column_stack([np.ones(x.size - order)] + [x[order - l: x.size - l] for l in range(1, order + 1)])
            y = x[order:]
            a, *_ = np.linalg.lstsq(X, y, rcond=None)
            num += float(np.sum((y - X @ a) ** 2))
            den += float(np.sum((y - y.mean()) ** 2))
    return 1.0 - num / den if den > 0 else math.nan


# -- long-run covariance of the score ------------------------------------------------------------
def _bandwidth(g: np.ndarray) -> float:
    """Andrews' (1991) AR(1) plug-in bandwidth for the Bartlett kernel (unit weights)."""
    n = g.shape[0]
    x0, x1 = g[:-1], g[1:]
    den = np.sum(x0 * x0, axis=0)
    ok = den > 0
    if n < 4 or not np.any(ok):
        return 0.0
    rho = np.clip(np.sum(x0 * x1, axis=0)[ok] / den[ok], -_RHO_CAP, _RHO_CAP)
    s2 = np.mean((x1[:, ok] - rho * x0[:, ok]) ** 2, axis=0)
    num = np.sum(4 * rho**2 * s2**2 / ((1 - rho) ** 6 * (1 + rho) ** 2))
    dnm = np.sum(s2**2 / (1 - rho) ** 4)
    a1 = num / dnm if dnm > 0 else 0.0
    return float(min(1.1447 * (a1 * n) ** (1 / 3), n - 1))


def _prewhiten(g: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-component AR(1) filter ``g*_k = g_k − a g_{k−1}``; returns ``(g*, a)``."""
    x0, x1 = g[:-1], g[1:]
    den = np.sum(x0 * x0, axis=0)
    a = np.where(den > 0, np.sum(x0 * x1, axis=0) / np.where(den > 0, den, 1.0), 0.0)
    a = np.clip(a, -_RHO_CAP, _RHO_CAP)
    return x1 - a * x0, a


def _bartlett(g: np.ndarray, L: float) -> np.ndarray:
    omega = g.T @ g
    for l in range(1, int(np.floor(L)) + 1):
        gl = g[:-l].T @ g[l:]
        omega = omega + (1.0 - l / (L + 1.0)) * (gl + gl.T)
    return omega


def _scores(J: np.ndarray, r: np.ndarray, mask: np.ndarray, n_channels: int) -> list[np.ndarray]:
    """Per run, the score series ``g_k = Σ_c J_kcᵀ r_kc`` over its real samples ``(n_i, p)``."""
    R, N = mask.shape
    p = J.shape[1]
    if J.shape[0] != R * N * n_channels:
        raise FitError(f"covariance: {J.shape[0]} residuals do not match {R} runs × {N} samples × "
                       f"{n_channels} channels")
    g = np.einsum("rncp,rnc->rnp", J.reshape(R, N, n_channels, p), r.reshape(R, N, n_channels))
    return [g[i, mask[i]] for i in range(R)]


def _lag1(g: np.ndarray) -> float:
    """The largest lag-1 autocorrelation over the score's components that carry variance."""
    x = g - g.mean(0)
    den = np.sum(x * x, axis=0)
    ok = den > 1e-12 * max(float(den.max()), 1e-300)
    if g.shape[0] < 3 or not np.any(ok):
        return 0.0
    return float(np.max(np.sum(x[:-1] * x[1:], axis=0)[ok] / den[ok]))


def aggregated(g: np.ndarray) -> tuple[np.ndarray, int]:
    """The score summed over consecutive blocks of ``b`` samples, ``b`` the smallest (growing by half) whose block
    sums have a lag-1 autocorrelation of at most :data:`_RHO_AGGREGATE`, keeping at least :data:`MIN_BLOCKS` blocks;
    returns ``(block sums, b)``. A last incomplete block is kept as it is: the sum of all scores is unchanged."""
    n = g.shape[0]
    b = 1
    while _lag1(_block_sums(g, b)) > _RHO_AGGREGATE:
        nb = max(b + 1, int(math.ceil(1.5 * b)))
        if n // nb < MIN_BLOCKS:
            break
        b = nb
    return _block_sums(g, b), b


def _block_sums(g: np.ndarray, b: int) -> np.ndarray:
    if b <= 1:
        return g
    n = g.shape[0]
    edges = np.arange(0, n, b)
    return np.add.reduceat(g, edges, axis=0)


def _hac_meat(scores: list[np.ndarray], p: int) -> tuple[np.ndarray, tuple[float, ...]]:
    """Per run, the long-run covariance of the (aggregated) score; the bandwidths in samples of the run."""
    omega = np.zeros((p, p))
    bws = []
    for g in scores:
        g, b = aggregated(g)
        if g.shape[0] < 4:
            omega += g.T @ g
            bws.append(0.0)
            continue
        gs, a = _prewhiten(g)
        L = _bandwidth(gs)
        back = 1.0 / (1.0 - a)
        omega += back[:, None] * _bartlett(gs, L) * back[None, :]
        bws.append(L * b)
    return omega, tuple(bws)


def _block_draws(scores: list[np.ndarray], p: int, n_boot: int, seed: int) -> tuple[np.ndarray, tuple[float, ...]]:
    """``n_boot`` moving-block resamples of the summed (centred) score: ``(n_boot, p)``."""
    rng = np.random.default_rng(seed)
    total = np.zeros((n_boot, p))
    bls = []
    for g in scores:
        g, agg = aggregated(g)  # the same block sums as "hac" (module docstring)
        n = g.shape[0]
        g = g - g.mean(0)
        b = int(np.clip(round(2 * max(_bandwidth(g), 1.0)), 1, n))
        bls.append(float(b * agg))
        c = np.concatenate([np.zeros((1, p)), np.cumsum(g, 0)])
        block_sums = c[b:] - c[:-b]  # (n - b + 1, p)
        k = int(np.ceil(n / b))
        picks = rng.integers(0, block_sums.shape[0], size=(n_boot, k))
        total += block_sums[picks].sum(1) * (n / (k * b))
    return total, tuple(bls)


# -- the covariance ------------------------------------------------------------------------------
def covariance(J: np.ndarray, r: np.ndarray, *, dof: int | None = None, rtol: float | None = None,
               involvement: float = 0.3, kind: str = "white", mask: np.ndarray | None = None, n_channels: int = 1,
               runs: tuple[str, ...] = (), channels: tuple[str, ...] = (), n_boot: int = 2000,
               seed: int = 0, input_meat: np.ndarray | None = None,
               input_noise: dict[str, float] | None = None, variance: float | None = None) -> Covariance:
    """Covariance of the unknowns at a least-squares optimum (see the module docstring).

    Args:
        J: Jacobian ``(m, p)`` of the residuals ``r`` ``(m,)`` at the optimum.
        dof: degrees of freedom for σ̂² (default ``m − p``, at least 1).
        rtol: relative singular-value cut-off (default ``1e3·ε·max(m, p)``).
        involvement: an unknown whose component in a dropped right-singular vector exceeds this
            (unit-norm vectors) is reported unidentifiable.
        kind: ``"white"``, ``"hac"``, ``"block"`` or ``"auto"``.
        mask: ``(R, N)`` real samples of each run, the residuals being laid out
            ``(run, sample, channel)``; needed for every kind but ``"white"`` (without it
            ``"auto"`` is ``"white"`` and no whiteness is computed).
        n_channels: number of channels per sample in that layout.
        runs, channels: labels for the whiteness table.
        n_boot, seed: resamples and random seed of ``"block"``.
        input_meat: Ω_u ``(p, p)`` of measured-input noise (added to the sandwich).
        input_noise: the input noise levels behind ``input_meat`` (for the description).
        variance: use this σ̂² instead of estimating it from ``r`` (e.g. 1 for residuals already
            normalised by their noise level, as with prior rows stacked under scaled data rows).
    """
    if kind not in KINDS:
        raise FitError(f"covariance kind must be one of {', '.join(KINDS)}, got {kind!r}")
    J = np.asarray(J, dtype=np.float64)
    r = np.asarray(r, dtype=np.float64)
    m, p = J.shape
    dof = max(m - p, 1) if dof is None else max(int(dof), 1)
    s2 = float(r @ r) / dof if variance is None else float(variance)
    white = None
    if mask is not None:
        mask = np.asarray(mask, dtype=bool)
        white = whiteness(r, mask, n_channels, runs=runs, channels=channels)
    elif kind in ("hac", "block"):
        raise FitError(f"covariance kind {kind!r} needs the residuals' run layout (mask)")
    if kind == "auto":
        kind = "white" if white is None or white.white else "hac"
    if p == 0:
        return Covariance(np.zeros((0, 0)), s2, np.zeros(0), 0, (), kind, (), white)
    # the singular values and right vectors of J are those of R in J = QR (a tall J: the thin QR
    # first is 2-3x faster than the SVD of J itself, 43 218 x 34: 20 ms against 47 ms)
    _, sv, vt = np.linalg.svd(np.linalg.qr(J, mode="r") if m > 2 * p else J, full_matrices=False)
    tol = (sv[0] if sv.size else 0.0) * (rtol if rtol is not None else max(m, p) * np.finfo(float).eps * 1e3)
    keep = sv > tol
    inv = (vt[keep].T / sv[keep] ** 2) @ vt[keep]
    bandwidth: tuple[float, ...] = ()
    if kind == "white":
        mat = s2 * inv
    else:
        n_scores = int(mask.sum())
        correction = n_scores / max(n_scores - p, 1)
        scores = _scores(J, r, mask, n_channels)
        if kind == "hac":
            omega, bandwidth = _hac_meat(scores, p)
            mat = correction * inv @ omega @ inv
        else:
            draws, bandwidth = _block_draws(scores, p, n_boot, seed)
            dz = draws @ inv
            mat = correction * (dz.T @ dz) / n_boot
        mat = 0.5 * (mat + mat.T)
    if input_meat is not None:
        mat = mat + inv @ np.asarray(input_meat, dtype=np.float64) @ inv
        mat = 0.5 * (mat + mat.T)
    bad: tuple[int, ...] = ()
    if not np.all(keep):
        involved = np.any(np.abs(vt[~keep]) > involvement, axis=0)
        bad = tuple(int(i) for i in np.flatnonzero(involved))
        mat = mat + np.diag(np.where(involved, np.inf, 0.0))
    eiv = dict(input_noise or {}) if input_meat is not None else {}
    return Covariance(mat, s2, sv, int(np.sum(keep)), bad, kind, bandwidth, white, eiv)


def relabelled(cov: np.ndarray, values: dict[str, float], new: dict[str, float], free: tuple[str, ...]) -> np.ndarray:
    """``cov`` (over ``free``) with rows and columns permuted after a canonical relabelling of
    interchangeable parameters (``new = model.canonical(values)``, e.g. Nomoto T1 ↔ T2)."""
    perm = []
    for n in free:
        match = [i for i, m in enumerate(free) if values[m] == new[n]]
        perm.append(match[0] if match else free.index(n))
    return cov[np.ix_(perm, perm)]
