r"""The fast screen of structure discovery: equation error on smoothed derivatives, sparse selection.

The base model's equation-error form (inverse dynamics in force space for a 3-DOF model,
:math:`e = M\dot\nu + C(\nu)\nu + D(\nu)\nu - \tau`) is affine in its free coefficients θ, and a
library term adds :math:`-c_k\phi_k(\nu)` to its equation, so on the smoothed, differentiated
samples (:func:`diffship.fit.equation_error.equation_samples`) the whole library is one linear
regression

.. math:: -b_0 = A\theta - \Phi c + e, \qquad A = \partial e/\partial\theta \ (\text{forward mode, exact}),

each equation divided by its residual RMS (feasible GLS, two passes). Selection is **sequentially
thresholded least squares** (STLSQ; Brunton, Proctor & Kutz, PNAS 113, 2016): least squares, drop the
library terms whose contribution (coefficient × the RMS of its regressor) is below ``threshold`` times
the RMS force of their equation, refit, repeat. The base coefficients are never dropped. Bagging the
selection over a moving-block bootstrap of the samples (blocks of ``block_s`` seconds: the equation
residuals of filtered data are coloured; Fasel et al., Proc. R. Soc. A 478, 2022, "ensemble SINDy")
gives each term's **frequency**, the fraction of resamples that keep it. It measures how stable the
selection is, not whether it is right: the regression has noisy regressors and derivatives (errors in
variables) and its bias is the same in every resample — on plain-fossen3 USV data with real-log noise it
estimates X_u̇ = +3579 kg (truth −400) and keeps a spurious X_v_v (v²) in every resample. Discovery therefore
only takes its proposals; inclusion probabilities come from the output-error ranking (:mod:`.rank`).

The screen only proposes structures: each is refitted by output error and ranked on output residuals
(:mod:`.rank`), because a model that matches derivatives need not simulate well.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Float

from ..data import Run
from ..models import AbstractModel
from ..models.terms import term_class
from ..params import ParamSpec
from ..preprocess import Filter
from ..stats import block_indices
from ..fit.equation_error import equation_samples

__all__ = ["Screen", "screen", "forward", "stlsq"]



@dataclasses.dataclass(frozen=True)
class Screen:
    """What the screen found.

    Attributes:
        terms: the library screened, in order.
        coefficients: ``{term: value}`` of the STLSQ fit at ``threshold`` on all samples (0: dropped).
        base: ``{parameter: value}`` of the base's free coefficients in that fit.
        inclusion: ``{term: fraction of bootstrap resamples that keep it}``.
        path: ``{k: the first k terms}`` of the forward selection on all samples.
        contribution: ``{term: RMS force of the term / RMS force of its equation}`` in the full least squares.
        threshold (the smallest relative gain that adds a term), n_boot, block_s: the settings.
    """

    terms: tuple[str, ...]
    coefficients: dict[str, float]
    base: dict[str, float]
    inclusion: dict[str, float]
    path: dict[int, tuple[str, ...]]
    contribution: dict[str, float]
    threshold: float
    n_boot: int
    block_s: float

    def candidates(self, max_terms: int, min_inclusion: float = 0.1) -> list[tuple[str, ...]]:
        """Structures to refit: none, the selection path, and the terms nested by inclusion
        probability (those kept by at least ``min_inclusion`` of the resamples), each at most
        ``max_terms`` long, duplicates dropped, in that order."""
        ranked = sorted((t for t in self.terms if self.inclusion[t] >= min_inclusion),
                        key=lambda t: (-self.inclusion[t], -self.contribution[t]))
        out: list[tuple[str, ...]] = [()]
        for sel in self.path.values():
            out.append(sel[:max_terms])
        for k in range(1, min(max_terms, len(ranked)) + 1):
            out.append(tuple(ranked[:k]))
        seen, unique = set(), []
        for c in out:
            key = frozenset(c)
            if key not in seen:
                seen.add(key)
                unique.append(tuple(t for t in self.terms if t in c))
        return unique


def stlsq(X: Float[np.ndarray, "n p"], y: Float[np.ndarray, " n"], keep: int, threshold: Float[np.ndarray, " q"],
          max_iter: int = 10) -> Float[np.ndarray, " p"]:
    """Sequentially thresholded least squares: the first ``keep`` columns always stay; a later column
    ``k`` is dropped while ``|ξ_k|·RMS(X_k) < threshold[k - keep]``."""
    norms = np.sqrt(np.mean(X**2, axis=0))
    norms = np.where(norms > 0, norms, 1.0)
    Xn = X / norms
    active = np.ones(X.shape[1], dtype=bool)
    xi = np.zeros(X.shape[1])
    for _ in range(max_iter):
        xi[:] = 0.0
        xi[active], *_ = np.linalg.lstsq(Xn[:, active], y, rcond=None)
        small = np.zeros_like(active)
        small[keep:] = active[keep:] & (np.abs(xi[keep:]) < threshold)
        if not small.any():
            break
        active &= ~small
    xi[~active] = 0.0
    return xi / norms


def _design(base: AbstractModel, spec: ParamSpec, terms: Sequence[str], runs: Sequence[Run], flt: Filter):
    """``(X, y, eq, names_base)``: rows of every sample and equation, columns base coefficients then terms."""
    s = equation_samples(base, runs, flt)
    z, zd, zdd, u = (jnp.asarray(a) for a in s)
    free = spec.free_names
    values = spec.values()
    theta0 = jnp.asarray([values[n] for n in free])

    def resid(th):
        m = base.with_params({**values, **dict(zip(free, th))})
        return jax.vmap(m.equation_residual)(z, zd, zdd, u)

    e0 = np.asarray(resid(theta0))
    A = np.asarray(jax.jacfwd(resid)(theta0))  # (n, n_eq, p)
    b0 = e0 - A @ np.asarray(theta0)
    n, n_eq = e0.shape
    iu = list(base.EQUATION_CHANNELS).index("u")
    uu, vv, rr = (s.z[:, iu + k] for k in range(3))
    Phi = np.zeros((n, n_eq, len(terms)))
    for k, t in enumerate(terms):
        cls = term_class(t)
        Phi[:, base.EQUATIONS.index(cls.equation), k] = np.asarray(cls.regressor(uu, vv, rr))
    X = np.concatenate([A, -Phi], axis=2)
    return X, -b0


def forward(X: Float[np.ndarray, "n p"], y: Float[np.ndarray, " n"], keep: int, max_terms: int,
            min_gain: float) -> list[int]:
    """Greedy forward selection: from the first ``keep`` columns, add the column (index ≥ ``keep``)
    that lowers the residual sum of squares most, while it lowers it by at least ``min_gain`` of
    itself and fewer than ``max_terms`` are in; the added columns' indices, in order. Marginal
    gains, unlike thresholded coefficients, are not fooled by collinear terms that cancel."""
    chosen: list[int] = []
    base = list(range(keep))
    G, b, yy = X.T @ X, X.T @ y, float(y @ y)  # normal equations: each trial is a small solve

    def rss(cols):
        Gs = G[np.ix_(cols, cols)] + 1e-10 * np.trace(G) / len(G) * np.eye(len(cols))
        return yy - float(b[cols] @ np.linalg.solve(Gs, b[cols]))

    now = rss(base)
    rest = list(range(keep, X.shape[1]))
    while rest and len(chosen) < max_terms:
        gains = [(now - rss(base + chosen + [k]), k) for k in rest]
        g, k = max(gains)
        if not g > min_gain * now:
            break
        chosen.append(k)
        rest.remove(k)
        now -= g
    return chosen


def screen(base: AbstractModel, runs: Sequence[Run], spec: ParamSpec, terms: Sequence[str], *,
           max_terms: int = 6, min_gain: float = 0.003, n_boot: int = 30, block_s: float = 5.0,
           flt: Filter = Filter("butter", cutoff=1.0), seed: int = 0) -> Screen:
    """Screen the library ``terms`` on ``runs`` (module docstring); ``spec``: the base model's free
    coefficients (they are always in the regression) and fixed values."""
    terms = tuple(terms)
    X3, y2 = _design(base, spec, terms, runs, flt)  # (n, n_eq, p), (n, n_eq)
    n, n_eq, p = X3.shape
    keep = len(spec.free_names)
    # feasible GLS: each equation divided by its residual RMS after an ordinary least-squares pass
    level = np.sqrt(np.mean(y2**2, axis=0))
    level = np.where(level > 0, level, 1.0)
    Xl, yl = X3 / level[None, :, None], y2 / level[None, :]
    coef, *_ = np.linalg.lstsq(Xl[:, :, :keep].reshape(n * n_eq, keep), yl.reshape(-1), rcond=None)
    res = y2 - np.einsum("nep,p->ne", X3[:, :, :keep], coef)
    w = np.sqrt(np.mean(res**2, axis=0))
    w = np.where(w > 0, w, 1.0)
    Xg, yg = X3 / w[None, :, None], y2 / w[None, :]
    norms = np.sqrt(np.mean(Xg.reshape(-1, p) ** 2, axis=0))
    Xg = Xg / np.where(norms > 0, norms, 1.0)

    def select(idx):
        return forward(Xg[idx].reshape(-1, p), yg[idx].reshape(-1), keep, max_terms, min_gain)

    order = select(np.arange(n))
    X, y = Xg.reshape(-1, p), yg.reshape(-1)
    cols = list(range(keep)) + order
    c, *_ = np.linalg.lstsq(X[:, cols], y, rcond=None)
    full = np.zeros(p)
    full[cols] = c
    full = full / np.where(norms > 0, norms, 1.0)
    eq_of = np.array([list(base.EQUATIONS).index(term_class(t).equation) for t in terms], dtype=int)
    contribution = {t: float(abs(full[keep + k]) * np.sqrt(np.mean(X3[:, eq_of[k], keep + k] ** 2)) / level[eq_of[k]])
                    for k, t in enumerate(terms)}
    path = {i + 1: tuple(terms[j - keep] for j in order[:i + 1]) for i in range(len(order))}
    dt = float(np.median(np.diff(runs[0].time))) if runs else 0.1
    block = max(1, int(round(block_s / dt)))
    hits = np.zeros(len(terms))
    for idx in block_indices(n, n_boot, block, np.random.default_rng(seed)):
        for j in select(idx):
            hits[j - keep] += 1
    return Screen(terms=terms, coefficients={t: float(full[keep + k]) for k, t in enumerate(terms)},
                  base={nm: float(full[i]) for i, nm in enumerate(spec.free_names)},
                  inclusion={t: float(hits[k] / max(n_boot, 1)) for k, t in enumerate(terms)},
                  path=path, contribution=contribution, threshold=min_gain, n_boot=n_boot, block_s=block_s)
