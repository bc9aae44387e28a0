r"""Integrators: how a model's vector field is advanced over one sample interval.

Every simulation in diffship (fits, evaluation, diagnosis, closed-loop manoeuvres) advances the
state from one sample time to the next with the inputs held on a first-order hold,

.. math::
    u(t) = u_k + \frac{t - t_k}{t_{k+1} - t_k}\,(u_{k+1} - u_k), \qquad t_k \le t \le t_{k+1},

through one method, :meth:`AbstractIntegrator.interval`. An integrator is a small
:class:`equinox.Module` chosen once and carried with a fit (:class:`~diffship.fit.FitResult`
records it), so that a fit is evaluated and diagnosed with the integrator it was made with.

* :class:`Diffrax` — a diffrax solver (:class:`ClassicalRK4`, a Butcher tableau over diffrax's
  ``AbstractERK``, by default; or ``diffrax.Tsit5()``, ...) stepped with its own ``step`` method
  ``substeps`` times per sample interval: diffrax's tableau and stage machinery, our sample grid;
* :class:`RK4` — the same classical Runge–Kutta 4 written out by hand (kept as an option: see
  ``benchmarks/integrators_speed.py`` for the measured difference);
* :class:`Tsit5` — diffrax's Tsitouras 5(4) with a PID step-size controller inside each interval
  and ``adjoint=diffrax.ForwardMode()``, so forward-mode Jacobians (what Levenberg–Marquardt
  needs) go through the solver.

Both are pure JAX and forward-differentiable; batching over runs is ``jax.vmap`` outside.

References:
    J. C. Butcher, *Numerical Methods for Ordinary Differential Equations*, 3rd ed., Wiley 2016.
    Ch. Tsitouras, "Runge–Kutta pairs of order 5(4) satisfying only the first column simplifying
    assumption", Computers & Mathematics with Applications 62 (2011).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import ClassVar

import diffrax
import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

__all__ = ["AbstractIntegrator", "ClassicalRK4", "Diffrax", "HOLDS", "RK4", "Tsit5", "get_integrator", "INTEGRATORS"]

VectorField = Callable[[Float[Array, ""], Float[Array, " n_x"], Float[Array, " n_u"]], Float[Array, " n_x"]]


HOLDS = ("linear", "zero")


class AbstractIntegrator(eqx.Module):
    r"""Advance ``ẋ = f(t, x, u(t))`` over one sample interval, the input held between its samples.

    ``hold`` is the convention that says what a logged input did between two samples
    :math:`u_k = u(t_k)`, :math:`u_{k+1} = u(t_{k+1})`:

    * ``"linear"`` (first-order hold, the default): :math:`u(t) = u_k + (t - t_k)/(t_{k+1} - t_k)\,(u_{k+1} - u_k)`,
      right for a sampled continuous signal (a rudder angle, a measured force);
    * ``"zero"`` (zero-order hold): :math:`u(t) = u_k` on :math:`[t_k, t_{k+1})`, right for a digital command
      that a controller sets at each sample and holds (a thrust set-point at 10 Hz). Read under the
      linear convention, such a log leads the true input by half a sample (Franklin, Powell & Workman,
      *Digital Control of Dynamic Systems*, 3rd ed., 1998, §6.2): a structural error that a fit or a
      discovery would try to explain otherwise.
    """

    name: str = eqx.field(static=True, default="abstract")
    hold: str = eqx.field(static=True, default="linear", kw_only=True)

    def __check_init__(self):
        if self.hold not in HOLDS:
            raise ValueError(f"input hold {self.hold!r}: use one of {', '.join(HOLDS)}")

    def held(self, u0, u1):
        """The inputs at the interval's ends as the interpolation sees them (``hold``)."""
        return (u0, u0) if self.hold == "zero" else (u0, u1)

    def _hold_text(self) -> str:
        return "; inputs held constant over each sample (zero-order hold)" if self.hold == "zero" else ""

    def interval(
        self,
        f: VectorField,
        t0: Float[Array, ""],
        t1: Float[Array, ""],
        x: Float[Array, " n_x"],
        u0: Float[Array, " n_u"],
        u1: Float[Array, " n_u"],
    ) -> Float[Array, " n_x"]:
        """The state at ``t1`` from ``x`` at ``t0``, inputs linear from ``u0`` to ``u1``."""
        raise NotImplementedError

    def describe(self) -> str:
        """One line for reports."""
        raise NotImplementedError


class RK4(AbstractIntegrator):
    r"""Classical Runge–Kutta 4, ``substeps`` equal steps per sample interval.

    .. math::
        k_1 = f(t, x, u_a),\; k_2 = f(t + h/2, x + h k_1/2, u_b),\; k_3 = f(t + h/2, x + h k_2/2, u_b),
        \; k_4 = f(t + h, x + h k_3, u_c),\quad x^+ = x + \tfrac h6(k_1 + 2k_2 + 2k_3 + k_4)

    with ``u_a, u_b, u_c`` the held input at the start, middle and end of the step. The substeps
    are unrolled (``substeps`` is small and static).
    """

    substeps: int = eqx.field(static=True, default=1)
    name: str = eqx.field(static=True, default="rk4")

    def __check_init__(self):
        if not (isinstance(self.substeps, int) and self.substeps >= 1):
            raise ValueError(f"RK4: substeps must be a positive integer, got {self.substeps!r}")

    def interval(self, f, t0, t1, x, u0, u1):
        u0, u1 = self.held(u0, u1)
        n = self.substeps
        h = (t1 - t0) / n
        du = (u1 - u0) / n
        y = x
        for k in range(n):
            t = t0 + k * h
            ua, uc = u0 + k * du, u0 + (k + 1) * du
            ub = 0.5 * (ua + uc)
            k1 = f(t, y, ua)
            k2 = f(t + 0.5 * h, y + 0.5 * h * k1, ub)
            k3 = f(t + 0.5 * h, y + 0.5 * h * k2, ub)
            k4 = f(t + h, y + h * k3, uc)
            y = y + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        return y

    def describe(self) -> str:
        return f"fixed-step RK4, {self.substeps} step(s) per sample" + self._hold_text()


class ClassicalRK4(diffrax.AbstractERK):
    """The classical Runge–Kutta 4 as a diffrax solver (diffrax has none): a Butcher tableau.

    No embedded error estimate (``b_error`` is zero): for fixed steps only.
    """

    tableau: ClassVar[diffrax.ButcherTableau] = diffrax.ButcherTableau(
        c=np.array([0.5, 0.5, 1.0]),
        b_sol=np.array([1 / 6, 1 / 3, 1 / 3, 1 / 6]),
        b_error=np.zeros(4),
        a_lower=(np.array([0.5]), np.array([0.0, 0.5]), np.array([0.0, 0.0, 1.0])),
    )
    interpolation_cls: ClassVar[Callable[..., diffrax.ThirdOrderHermitePolynomialInterpolation]] = (
        diffrax.ThirdOrderHermitePolynomialInterpolation.from_k
    )

    def order(self, terms):
        del terms
        return 4


class Diffrax(AbstractIntegrator):
    r"""A diffrax solver driven on the sample grid.

    Each sample interval is split into ``substeps`` equal steps; the input is held on a
    first-order hold inside the interval (a closure over ``u0``, ``u1``, so there is no kink
    inside a step). No step-size control and no ``diffeqsolve`` loop: the scan over samples in
    :func:`diffship.simulate.integrate` is the only loop, which keeps the forward-mode Jacobian
    cheap. Use an explicit solver (``ClassicalRK4()``, ``diffrax.Tsit5()``, ``diffrax.Heun()``, ...).

    **Stages.** diffrax's ``step`` evaluates the stages of a Runge–Kutta method in a loop of its
    own (an ``eqxi.while_loop`` over the stages, with buffers), nested inside every time step:
    on a CPU that loop costs about as much as the vector field in the forward-mode Jacobian
    (diffrax-rk4 53.8 ms against 29.2 ms for the same RK4 written out, ``benchmarks/results/
    integrators_speed.md``), and on a GPU each stage iteration is a separate round of kernel
    launches (measured: 157 µs per step against 17.8 µs for a plain ``lax.scan`` RK4). With
    ``unroll=True`` an explicit solver's diffrax Butcher tableau
    (``solver.tableau``: ``c``, ``a_lower``, ``b_sol``) is evaluated with the stages written out,

    .. math::  k_i = f\big(t + c_i h,\; x + h\textstyle\sum_{j<i} a_{ij} k_j\big),\qquad
               x^+ = x + h\textstyle\sum_i b_i k_i

    (zero coefficients skipped, stages that feed neither ``b_sol`` nor a later needed stage — an
    FSAL stage kept only for the error estimate — left out): the same method and coefficients,
    one fused loop body per time step, equal to diffrax's ``step`` up to round-off (measured
    ≤ 3·10⁻¹⁵ on the residuals and Jacobian of the fossen3 benchmark problem, RK4 and Tsit5). Solvers
    without an explicit tableau, and ``unroll=False``, use diffrax's ``init``/``step``.

    ``unroll=True`` is the default on every backend: measured on the fossen3 benchmark problem
    (2 shared CPU cores under load 6.5, min of 7 interleaved calls) the forward-mode
    Jacobian takes 72 ms unrolled against 141 ms through diffrax's ``step`` (hand-written
    :class:`RK4`: 64 ms), the residual 5.7 against 7.5 ms; Tsit5: 115 against 231 ms and 14.4
    against 24.4 ms. On a GPU the nested stage loop is a round of kernel launches per stage.
    """

    solver: diffrax.AbstractSolver = eqx.field(static=True, default=ClassicalRK4(scan_kind="lax"))
    substeps: int = eqx.field(static=True, default=1)
    name: str = eqx.field(static=True, default="diffrax")
    unroll: bool = eqx.field(static=True, default=True)

    def _tableau(self):
        tab = getattr(self.solver, "tableau", None)
        if not self.unroll or not isinstance(tab, diffrax.ButcherTableau) or getattr(tab, "a_diagonal", None) is not None:
            return None
        if getattr(tab, "implicit", False) or getattr(self.solver, "implicit_term", None) is not None:
            return None
        return tab

    def interval(self, f, t0, t1, x, u0, u1):
        u0, u1 = self.held(u0, u1)
        span = t1 - t0

        def rhs(t, y, args):
            return f(t, y, u0 + (t - t0) / span * (u1 - u0))

        h = span / self.substeps
        tab = self._tableau()
        y = x
        if tab is not None:
            # the stages' inputs at their fixed fractions of the interval (static weights: no division
            # by the interval's length inside the time step, which XLA keeps as a kernel of its own)
            du = u1 - u0
            return _explicit_rk(tab, lambda t, y, w: f(t, y, u0 + w * du), t0, h, x, self.substeps)
        term = diffrax.ODETerm(rhs)
        for k in range(self.substeps):
            ta = t0 + k * h
            tb = ta + h
            state = self.solver.init(term, ta, tb, y, None)
            y, _, _, _, _ = self.solver.step(term, ta, tb, y, None, state, made_jump=False)
        return y

    def describe(self) -> str:
        return (f"diffrax {type(self.solver).__name__} stepped on the sample grid, {self.substeps} step(s) per sample"
                + self._hold_text())


def _needed_stages(a_lower, b_sol) -> list[bool]:
    """Stages that feed the solution: a nonzero weight, or a nonzero coefficient in a needed later stage."""
    s = len(b_sol)
    need = [float(b) != 0.0 for b in b_sol]
    for i in range(s - 1, 0, -1):
        if need[i]:
            for j, a in enumerate(np.asarray(a_lower[i - 1])):
                need[j] = need[j] or float(a) != 0.0
    return need


def _explicit_rk(tab, rhs, t0, h, x, substeps: int):
    """``substeps`` steps of the explicit Runge–Kutta method ``tab`` (diffrax's tableau), stages written out;
    ``rhs(t, y, w)`` with ``w`` the stage time's fraction of the whole interval, ``(k + c_i) / substeps``
    (a Python float: the input at a stage is interpolated with a constant weight)."""
    b = np.asarray(tab.b_sol)
    c = np.concatenate([[0.0], np.asarray(tab.c)])
    need = _needed_stages(tab.a_lower, b)
    y = x
    for k in range(substeps):
        t = t0 + k * h
        ks = []
        for i in range(len(b)):
            if not need[i]:
                ks.append(None)
                continue
            yi = y
            if i:
                for j, a in enumerate(np.asarray(tab.a_lower[i - 1])):
                    if float(a) != 0.0:
                        yi = yi + (float(a) * h) * ks[j]
            ks.append(rhs(t + float(c[i]) * h, yi, (k + float(c[i])) / substeps))
        inc = None
        for i, bi in enumerate(b):
            if float(bi) != 0.0:
                term = float(bi) * ks[i]
                inc = term if inc is None else inc + term
        y = y + h * inc
    return y


class Tsit5(AbstractIntegrator):
    """diffrax Tsit5 with a PID controller (``rtol``, ``atol``) inside each sample interval.

    Each interval is one ``diffrax.diffeqsolve`` from ``t0`` to ``t1`` (the input is linear in
    between, so there is no kink inside an interval for the controller to trip over), with
    ``adjoint=diffrax.ForwardMode()`` and ``throw=False``: a failed solve returns non-finite
    values, which the simulator turns into a blow-up status.
    """

    rtol: float = eqx.field(static=True, default=1e-6)
    atol: float = eqx.field(static=True, default=1e-8)
    max_steps: int = eqx.field(static=True, default=64)
    name: str = eqx.field(static=True, default="tsit5")

    def interval(self, f, t0, t1, x, u0, u1):
        u0, u1 = self.held(u0, u1)
        span = t1 - t0

        def rhs(t, y, args):
            return f(t, y, u0 + (t - t0) / span * (u1 - u0))

        sol = diffrax.diffeqsolve(
            diffrax.ODETerm(rhs),
            diffrax.Tsit5(),
            t0=t0,
            t1=t1,
            dt0=span,
            y0=x,
            saveat=diffrax.SaveAt(t1=True),
            stepsize_controller=diffrax.PIDController(rtol=self.rtol, atol=self.atol),
            adjoint=diffrax.ForwardMode(),
            max_steps=self.max_steps,
            throw=False,
        )
        ok = sol.result == diffrax.RESULTS.successful
        return jnp.where(ok, sol.ys[-1], jnp.nan)

    def describe(self) -> str:
        return (f"diffrax Tsit5, adaptive (rtol {self.rtol:g}, atol {self.atol:g}) within each sample interval"
                + self._hold_text())


#: Integrators selectable by name (``--solver NAME``).
INTEGRATORS: dict[str, Callable[..., AbstractIntegrator]] = {
    "diffrax-rk4": Diffrax,
    "diffrax-tsit5": lambda **kw: Diffrax(solver=diffrax.Tsit5(scan_kind="lax"), **kw),
    "rk4": RK4,
    "tsit5": Tsit5,
}


def get_integrator(spec: str | AbstractIntegrator, **options) -> AbstractIntegrator:
    """An integrator from its name (see :data:`INTEGRATORS`) and options, or the object itself."""
    if isinstance(spec, AbstractIntegrator):
        return spec
    try:
        cls = INTEGRATORS[spec]
    except KeyError:
        raise ValueError(f"unknown integrator {spec!r}; choose one of: {', '.join(INTEGRATORS)}") from None
    return cls(**options)
