r"""Parameter covariance from a least-squares Jacobian (the one place it is computed).

At the optimum of :math:`\tfrac12\lVert r(z)\rVert^2` with ``m`` residuals and ``p`` unknowns,

.. math::
    \hat\sigma^2 = \frac{r^\top r}{m - p}, \qquad \mathrm{Cov}(\hat z) \approx \hat\sigma^2 (J^\top J)^{-1},

computed from the SVD :math:`J = U\Sigma V^\top` as :math:`\hat\sigma^2 V\Sigma^{-2}V^\top`. Where
``J`` is (numerically) rank deficient the inverse does not exist: the directions with singular
values below ``rtol·σ_max`` are dropped and every unknown that takes part in them gets an
**infinite** variance — never a pseudo-inverse's zero, which would claim perfect knowledge of a
parameter the data say nothing about. Standard errors of the model parameters follow by the
delta method (:meth:`diffship.params.ParamSpec.dtheta_dz`).
"""

from __future__ import annotations

import dataclasses

import numpy as np

__all__ = ["Covariance", "covariance", "relabelled"]


@dataclasses.dataclass(frozen=True, eq=False)
class Covariance:
    """Covariance of the unknowns and how it was obtained.

    Attributes:
        matrix: ``(p, p)``; rows/columns of unidentifiable unknowns hold ``inf`` on the diagonal.
        residual_variance: :math:`\\hat\\sigma^2`.
        singular_values: of ``J`` (descending).
        rank: number of singular values kept.
        unidentifiable: indices of the unknowns in the dropped directions.
    """

    matrix: np.ndarray
    residual_variance: float
    singular_values: np.ndarray
    rank: int
    unidentifiable: tuple[int, ...]

    @property
    def full_rank(self) -> bool:
        return not self.unidentifiable


def covariance(J: np.ndarray, r: np.ndarray, *, dof: int | None = None, rtol: float | None = None,
               involvement: float = 0.3, variance: float | None = None) -> Covariance:
    """``σ̂²(JᵀJ)⁻¹`` with rank-deficient directions flagged (see the module docstring).

    Args:
        J: Jacobian ``(m, p)`` of the residuals ``r`` ``(m,)`` at the optimum.
        dof: degrees of freedom for σ̂² (default ``m − p``, at least 1).
        rtol: relative singular-value cut-off (default ``1e3·ε·max(m, p)``).
        involvement: an unknown whose component in a dropped right-singular vector exceeds this
            (unit-norm vectors) is reported unidentifiable.
        variance: use this σ̂² instead of estimating it from ``r`` (e.g. 1 for residuals already
            normalised by their noise level, as with prior rows stacked under scaled data rows).
    """
    J = np.asarray(J, dtype=np.float64)
    r = np.asarray(r, dtype=np.float64)
    m, p = J.shape
    dof = max(m - p, 1) if dof is None else max(int(dof), 1)
    s2 = float(r @ r) / dof if variance is None else float(variance)
    if p == 0:
        return Covariance(np.zeros((0, 0)), s2, np.zeros(0), 0, ())
    _, sv, vt = np.linalg.svd(J, full_matrices=False)
    tol = (sv[0] if sv.size else 0.0) * (rtol if rtol is not None else max(m, p) * np.finfo(float).eps * 1e3)
    keep = sv > tol
    inv = (vt[keep].T / sv[keep] ** 2) @ vt[keep]
    bad: tuple[int, ...] = ()
    if not np.all(keep):
        involved = np.any(np.abs(vt[~keep]) > involvement, axis=0)
        bad = tuple(int(i) for i in np.flatnonzero(involved))
        inv = inv + np.diag(np.where(involved, np.inf, 0.0))
    return Covariance(s2 * inv, s2, sv, int(np.sum(keep)), bad)


def relabelled(cov: np.ndarray, values: dict[str, float], new: dict[str, float], free: tuple[str, ...]) -> np.ndarray:
    """``cov`` (over ``free``) with rows and columns permuted after a canonical relabelling of
    interchangeable parameters (``new = model.canonical(values)``, e.g. Nomoto T1 ↔ T2)."""
    perm = []
    for n in free:
        match = [i for i, m in enumerate(free) if values[m] == new[n]]
        perm.append(match[0] if match else free.index(n))
    return cov[np.ix_(perm, perm)]
