r"""Equation-error baseline: differentiate the data, then least squares on the equations.

Today's common practice (seeds 000–004), implemented on the same data and reported with the
same metrics as output error:

1. smooth the measured channels and differentiate them numerically
   (:class:`diffship.preprocess.Filter`: zero-phase Butterworth by default, Savitzky–Golay or
   none);
2. evaluate the model's equations on the measured states and derivatives:

   * Nomoto 1: :math:`e = \dot r - (K(\delta+\delta_0) - r)/T_1` (seed 001's regression on ṙ);
   * Nomoto 2: :math:`e = \ddot r - (K(\delta+\delta_0+T_3\dot\delta) - r - (T_1+T_2)\dot r)/(T_1T_2)`
     (``δ̇`` from the same filter);
   * Fossen 3-DOF, inverse dynamics in force space (seed 000 / 004):
     :math:`e = M\dot\nu + C(\nu)\nu + D(\nu)\nu - \tau`, affine in the added masses and damping
     derivatives when m, I_z and x_g are known — so the least-squares problem is linear;

3. minimise :math:`\sum_k \sum_j (e_j(t_k)/w_j)^2` over the free parameters by Gauss–Newton
   (one step is the exact linear least-squares solution for the affine cases), with ``w_j`` the
   residual RMS of equation ``j`` from a first unweighted pass (feasible generalised least
   squares). Standard errors are the classical ``σ̂²(JᵀJ)⁻¹``; they ignore the errors in the
   regressors and the correlation of filtered noise, which is one reason this baseline is
   biased and over-confident on noisy data.

Parameters are estimated unconstrained in model units (bounds are not imposed, as in the
seeds); a result outside a bound is reported in the messages.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence

import jax
import jax.numpy as jnp
import numpy as np

from ..data import Run
from ..errors import FitError, ModelError
from ..models import Fossen3, Nomoto1, Nomoto2
from ..models import AbstractModel
from ..params import ParamSpec
from ..preprocess import Filter, smooth_and_derivative
from ..simulate import initial_state, model_inputs
from .result import FitResult

__all__ = ["fit_equation_error", "equation_data"]

_TRIM = 0.02  # fraction of each run dropped at both ends (filter edge effects)


def _sd(run: Run, name: str, flt: Filter):
    y = np.asarray(run[name], dtype=np.float64)
    if name == "psi":
        y = np.unwrap(y)
    return smooth_and_derivative(run.time, y, flt, f"run {run.name}, column {name}")


def equation_data(model: AbstractModel, run: Run, flt: Filter) -> tuple[np.ndarray, ...]:
    """Measured signals the model's equations are evaluated on: ``(z, zdot, zddot, u)``.

    ``z`` holds the measured dynamic states, ``zdot``/``zddot`` their filtered derivatives.
    """
    if hasattr(model, "equation_data"):
        return model.equation_data(run, flt)
    u = model_inputs(model, run)
    if isinstance(model, (Nomoto1, Nomoto2)):
        if run.has("r"):
            r, rd = _sd(run, "r", flt)
        else:
            run.require(("psi",), "equation error (needs r or psi)")
            _, r = _sd(run, "psi", flt)
            _, rd = smooth_and_derivative(run.time, r, Filter("none"))
        rdd = smooth_and_derivative(run.time, rd, flt if flt.kind != "savgol" else Filter("none"))[1]
        if isinstance(model, Nomoto2):  # the rudder rate, for the T3 lead term
            u = np.concatenate([u, _sd(run, "delta", flt)[1][:, None]], axis=1)
        return np.stack([r], 1), np.stack([rd], 1), np.stack([rdd], 1), u
    if isinstance(model, Fossen3):
        run.require(("u", "v", "r"), "equation error for fossen3 (needs measured u, v, r)")
        cols = [_sd(run, c, flt) for c in ("u", "v", "r")]
        z = np.stack([c[0] for c in cols], 1)
        zd = np.stack([c[1] for c in cols], 1)
        return z, zd, np.zeros_like(zd), u
    raise ModelError(f"no equation-error baseline for model {model.name}")


def _residual_fn(model: AbstractModel):
    """Per-sample equation residual ``e(model, z, zd, zdd, u)`` and the equation names.

    A model can provide its own baseline with two methods: ``equation_data(run, flt) ->
    (z, zd, zdd, u)`` (NumPy arrays, one row per sample) and
    ``equation_residual(z, zd, zdd, u) -> e`` (JAX, one sample), plus a class variable
    ``EQUATIONS`` naming the entries of ``e``.
    """
    if hasattr(model, "equation_residual"):
        return (lambda m, z, zd, zdd, u: m.equation_residual(z, zd, zdd, u)), tuple(model.EQUATIONS)
    if isinstance(model, Nomoto1):
        def e(m, z, zd, zdd, u):
            return jnp.atleast_1d(zd[0] - (m.K * (u[0] + m.delta0) - z[0]) / m.T1)
        return e, ("r_dot",)
    if isinstance(model, Nomoto2):
        def e(m, z, zd, zdd, u):
            forcing = m.K * (u[0] + m.delta0 + m.T3 * u[1])
            return jnp.atleast_1d(zdd[0] - (forcing - z[0] - (m.T1 + m.T2) * zd[0]) / (m.T1 * m.T2))
        return e, ("r_ddot",)
    if isinstance(model, Fossen3):
        def e(m, z, zd, zdd, u):
            return m.mass_matrix() @ zd + m.coriolis_vector(z) + m.damping_vector(z) - m.forces(u, z)
        return e, ("X", "Y", "N")
    raise ModelError(f"no equation-error baseline for model {model.name}")


def _nomoto2_from_first_order(z, zd, u, one):
    """Fallback start when r̈ is too noisy for the 2nd-order regression: 1st-order fit, T2 = T1/10."""
    A = np.stack([z[:, 0], u[:, 0], one], 1)
    (a, b, c), *_ = np.linalg.lstsq(A, zd[:, 0], rcond=None)
    if a >= 0 or b == 0:
        return None
    T = -1.0 / a
    return {"K": b * T, "T1": T, "T2": 0.1 * T, "delta0": c / b}


def _nomoto_linear_start(model, Z, ZD, ZDD, U) -> dict[str, float] | None:
    """Seed 001's linear regression: ṙ = a r + b δ + c (1st order), r̈ = a r + b ṙ + c δ + d (2nd).

    The map back to (K, T, δ0) is a bijection where it is defined, so this is the exact
    least-squares solution when every parameter is free, and a start otherwise.
    """
    z, zd, zdd, u = (np.asarray(a) for a in (Z, ZD, ZDD, U))
    one = np.ones(z.shape[0])
    if isinstance(model, Nomoto1):
        A = np.stack([z[:, 0], u[:, 0], one], 1)
        (a, b, c), *_ = np.linalg.lstsq(A, zd[:, 0], rcond=None)
        if a >= 0 or b == 0:
            return None
        T1 = -1.0 / a
        K = b * T1
        return {"K": K, "T1": T1, "delta0": c / b}
    if isinstance(model, Nomoto2):
        A = np.stack([z[:, 0], zd[:, 0], u[:, 0], one, u[:, 1]], 1)
        (a, b, c, d, g), *_ = np.linalg.lstsq(A, zdd[:, 0], rcond=None)
        if a >= 0 or c == 0:
            return _nomoto2_from_first_order(z, zd, u, one)
        P = -1.0 / a
        S = -b * P
        from ..models.nomoto import nomoto2_from_polynomial

        T = nomoto2_from_polynomial(S, P) if P > 0 else None
        if T is None or T[1] <= 0:
            return _nomoto2_from_first_order(z, zd, u, one)
        return {"K": c * P, "T1": T[0], "T2": T[1], "delta0": d / c, "T3": g / c}
    return None


def fit_equation_error(
    model: AbstractModel,
    runs: Sequence[Run],
    *,
    spec: ParamSpec | None = None,
    flt: Filter = Filter(),
    max_steps: int = 50,
) -> FitResult:
    """Fit ``model`` to ``runs`` by equation error (see the module docstring)."""
    t_start = time.perf_counter()
    spec = spec or model.spec()
    model = model.with_params(spec.values())
    free = spec.free_names
    if not free:
        raise FitError("no free parameters: free at least one (remove it from --fix)")
    e_fn, eq_names = _residual_fn(model)
    data = [equation_data(model, r, flt) for r in runs]
    keep = []
    for (z, *_rest) in data:
        n = z.shape[0]
        k = int(_TRIM * n)
        keep.append(slice(k, n - k))
    Z = jnp.asarray(np.concatenate([d[0][s] for d, s in zip(data, keep)]))
    ZD = jnp.asarray(np.concatenate([d[1][s] for d, s in zip(data, keep)]))
    ZDD = jnp.asarray(np.concatenate([d[2][s] for d, s in zip(data, keep)]))
    U = jnp.asarray(np.concatenate([d[3][s] for d, s in zip(data, keep)]))
    idx = spec.free_index()
    names = model.param_names
    base = model.theta()

    def residuals(theta_free, w):
        th = base.at[idx].set(theta_free)
        m = model.with_params(th)
        e = jax.vmap(lambda z, zd, zdd, u: e_fn(m, z, zd, zdd, u))(Z, ZD, ZDD, U)
        return (e / w).reshape(-1)

    res_jit = jax.jit(residuals)
    jac_jit = jax.jit(jax.jacfwd(residuals))
    theta = np.asarray(base)[idx]
    linear_start = _nomoto_linear_start(model, Z, ZD, ZDD, U)
    if linear_start is not None:
        theta = np.array([linear_start.get(n, float(base[i])) for n, i in zip(free, idx)])
    n_eq = len(eq_names)
    w = np.ones(n_eq)
    messages = [f"derivatives: {flt.describe(runs[0].dt)}", f"equations: {', '.join(eq_names)}"]
    iterations = 0
    converged = False
    compile_s = 0.0
    for weighting_pass in range(2):
        wj = jnp.asarray(w)
        t_c = time.perf_counter()
        r = np.asarray(res_jit(jnp.asarray(theta), wj))
        if iterations == 0:
            jac_jit(jnp.asarray(theta), wj).block_until_ready()
            compile_s = time.perf_counter() - t_c
        cost = 0.5 * float(r @ r)
        converged = False
        for _ in range(max_steps):
            J = np.asarray(jac_jit(jnp.asarray(theta), wj))
            iterations += 1
            step, *_ = np.linalg.lstsq(J, -r, rcond=None)
            scale = 1.0
            while scale > 1e-6:
                cand = theta + scale * step
                rc = np.asarray(res_jit(jnp.asarray(cand), wj))
                cc = 0.5 * float(rc @ rc)
                if math.isfinite(cc) and cc <= cost:
                    break
                scale *= 0.5
            else:
                break
            small = np.all(np.abs(scale * step) <= 1e-10 + 1e-8 * np.abs(theta))
            theta, r, cost = cand, rc, cc
            if small or abs(cost - cc) < 0:
                converged = True
                break
            if np.all(np.abs(scale * step) <= 1e-7 * (np.abs(theta) + 1e-12)):
                converged = True
                break
        if weighting_pass == 0:
            e = r.reshape(-1, n_eq) * w
            w = np.sqrt(np.mean(e * e, axis=0)) + 1e-300
    if not np.all(np.isfinite(theta)):
        raise FitError(f"equation error for {model.name} produced non-finite parameters on runs "
                       f"{', '.join(r_.name for r_ in runs)}; check the inputs and the filter")
    J = np.asarray(jac_jit(jnp.asarray(theta), jnp.asarray(w)))
    dof = max(r.size - len(free), 1)
    s2 = float(r @ r) / dof
    try:
        cov = s2 * np.linalg.pinv(J.T @ J)
    except np.linalg.LinAlgError:
        cov = np.full((len(free), len(free)), np.nan)
    vals = {n: float(v) for n, v in zip(names, np.asarray(base))}
    vals.update({n: float(theta[i]) for i, n in enumerate(free)})
    if isinstance(model, Nomoto2):
        swapped = Nomoto2.canonical(vals)
        if swapped != vals:
            perm = [free.index("T2") if n == "T1" else free.index("T1") if n == "T2" else free.index(n) for n in free]
            cov = cov[np.ix_(perm, perm)]
            vals = swapped
    stderr = {n: float(math.sqrt(max(cov[i, i], 0.0))) for i, n in enumerate(free)}
    for n in free:
        p = spec[n]
        if not (p.lower < vals[n] < p.upper):
            messages.append(f"{n} = {vals[n]:.4g} lies outside its physical bounds ({p.lower:g}, {p.upper:g})")
    fitted = model.with_params(vals)
    x0s = tuple(initial_state(fitted, run, flt) for run in runs)
    fit_s = time.perf_counter() - t_start - compile_s
    return FitResult(
        method="equation_error",
        model=fitted,
        params=vals,
        stderr=stderr,
        free=free,
        converged=bool(converged),
        status="converged" if converged else "Gauss–Newton did not settle",
        iterations=iterations,
        cost=0.5 * float(r @ r),
        fit_seconds=fit_s,
        compile_seconds=compile_s,
        channels=eq_names,
        channel_scales={n: float(x) for n, x in zip(eq_names, w)},
        noise_std={n: float(x) for n, x in zip(eq_names, np.sqrt(np.mean((r.reshape(-1, n_eq) * w) ** 2, axis=0)))},
        initial_states=x0s,
        run_names=tuple(r_.name for r_ in runs),
        covariance=cov,
        messages=tuple(messages),
        info={"filter": flt.describe(runs[0].dt), "equations": eq_names},
    )
