r"""Free-decay identification: damping from a velocity or angle left to die out.

Two classical tests, each identified two ways — by the direct curve fit of the test's closed-form
solution, and by the general output-error path with a small 1-DOF model:

**First order** (surge, sway, yaw; the craft is brought to a steady speed and the thrust is cut):

.. math::
    m\dot x + D x = \tau \;\Rightarrow\; x(t) = x_0 e^{-(D/m)t} \quad (\tau = 0)

``m`` is the total inertia of the DOF (rigid body + added mass, given), ``D`` the linear
damping (``D = −X_u`` etc. in Fossen's sign convention). The decay rate ``s = D/m`` is fitted
either by nonlinear least squares on :math:`x_0 e^{-st}` (``method="curve_fit"``) or by a
straight line through :math:`\ln x` (``method="loglinear"``; only samples well above the
noise are used, since the log amplifies noise at small |x|).

**Second order** (roll, pitch; the craft is heeled and released):

.. math::
    I\ddot\phi + b\dot\phi + k\phi = \tau \;\Rightarrow\;
    \phi(t) = A e^{-\zeta\omega_n t}\cos(\omega_d t + \varphi) + c,\quad
    \omega_d = \omega_n\sqrt{1 - \zeta^2}

with ``I`` the total inertia, ``k`` the restoring stiffness (e.g. :math:`\rho g\nabla\,GM_T`
for roll, :math:`z_{gb}W` for a submerged vehicle). From the fitted ζ and ω_n:
:math:`b = 2\zeta\omega_n I` given I, or :math:`b = 2\zeta k/\omega_n` given k; with both
given the two values differ when the I, k pair is inconsistent with the measured period (the
result reports both and the inertia the period implies, :math:`I = k/\omega_n^2`).

The 1-DOF models :class:`~diffship.models.decay.Decay1` (``"decay1"``) and
:class:`~diffship.models.decay.Decay2` (``"decay2"``; defined in :mod:`diffship.models.decay`,
re-exported here) put the
same equations in the output-error machinery (:func:`diffship.fit.fit_output_error`): channel
``velocity`` (first order) or ``angle`` (second order; ``rate`` optional), input ``tau``
(zero in a free decay; a force or moment step for the "inhomogeneous" build-up test).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy import optimize

from .errors import DataError
from .fit.covariance import covariance
from .models.decay import Decay1, Decay2

__all__ = ["FirstOrderDecay", "SecondOrderDecay", "fit_first_order_decay", "fit_second_order_decay",
           "Decay1", "Decay2", "decay_run", "curve_fit_runs", "curve_fit_text", "main", "plot_curve_fits"]


@dataclasses.dataclass(frozen=True)
class FirstOrderDecay:
    """Result of a first-order decay fit: ``x(t) = x0·exp(−rate·t)``, ``damping = rate·mass``."""

    x0: float
    rate: float  # 1/s
    damping: float  # D = rate·mass [N s/m or N m s/rad]
    rate_stderr: float
    damping_stderr: float
    time_constant: float  # 1/rate [s]
    method: str
    rmse: float


@dataclasses.dataclass(frozen=True)
class SecondOrderDecay:
    """Result of a damped-oscillation fit (see the module docstring)."""

    amplitude: float
    zeta: float
    omega_n: float  # rad/s
    omega_d: float  # rad/s
    phase: float
    offset: float
    damping_from_inertia: float  # b = 2ζω_n I (nan if I not given)
    damping_from_stiffness: float  # b = 2ζk/ω_n (nan if k not given)
    implied_inertia: float  # k/ω_n² (nan if k not given)
    zeta_stderr: float
    omega_n_stderr: float
    method: str
    rmse: float
    damping_from_inertia_stderr: float = float("nan")  # delta method, I taken as exact
    damping_from_stiffness_stderr: float = float("nan")  # delta method, k taken as exact
    implied_inertia_stderr: float = float("nan")  # delta method, k taken as exact

    @property
    def period(self) -> float:
        """Damped natural period 2π/ω_d [s]."""
        return 2 * math.pi / self.omega_d


def _check(t, y, what):
    t = np.asarray(t, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    if t.shape != y.shape or t.ndim != 1 or t.size < 5:
        raise DataError(f"{what}: need matching 1-D time and signal arrays with at least 5 samples")
    if not np.all(np.isfinite(y)):
        raise DataError(f"{what}: the signal contains NaN or inf; drop those samples first")
    return t - t[0], y


def fit_first_order_decay(t, y, mass: float = 1.0, *, method: str = "curve_fit",
                          floor: float | None = None) -> FirstOrderDecay:
    """Fit ``y = x0·exp(−s t)`` to a decaying velocity (time measured from the first sample).

    Args:
        t, y: samples of the decay (from the moment the input is cut).
        mass: total inertia m (rigid body + added) of the DOF, for ``damping = s·m``.
        method: ``"curve_fit"`` (nonlinear least squares, scipy) or ``"loglinear"`` (least
            squares line through ``ln|y|`` on the samples with ``|y| > floor``).
        floor: for ``"loglinear"``: the smallest |y| used (default 10 % of the first value).
    """
    t, y = _check(t, y, "first-order decay")
    if method == "loglinear":
        fl = floor if floor is not None else 0.1 * abs(y[0])
        keep = np.abs(y) > fl
        if keep.sum() < 3 or np.any(np.sign(y[keep]) != np.sign(y[0])):
            raise DataError("first-order decay (loglinear): too few samples above the floor, or the signal changes "
                            "sign; use method='curve_fit'")
        A = np.stack([np.ones(keep.sum()), -t[keep]], 1)
        coef, res, *_ = np.linalg.lstsq(A, np.log(np.abs(y[keep])), rcond=None)
        lnx0, s = coef
        resid = np.log(np.abs(y[keep])) - A @ coef
        cov = covariance(A, resid).matrix  # J = ∂(model)/∂(ln x0, s) up to sign
        x0 = math.copysign(math.exp(lnx0), y[0])
        s_se = math.sqrt(cov[1, 1])
    elif method == "curve_fit":
        # start from the log-linear estimate on the first part of the decay
        k = max(3, int(np.argmax(np.abs(y) < 0.37 * abs(y[0]))) or t.size // 3)
        s0 = 1.0 / max(t[min(k, t.size - 1)], 1e-9)
        popt, pcov = optimize.curve_fit(lambda tt, a, s: a * np.exp(-s * tt), t, y, p0=(y[0], s0))
        x0, s = float(popt[0]), float(popt[1])
        s_se = float(math.sqrt(max(pcov[1, 1], 0.0)))
    else:
        raise DataError(f"unknown method {method!r}: use 'curve_fit' or 'loglinear'")
    pred = x0 * np.exp(-s * t)
    return FirstOrderDecay(x0=float(x0), rate=float(s), damping=float(s * mass), rate_stderr=s_se,
                           damping_stderr=s_se * mass, time_constant=float(1.0 / s) if s != 0 else math.inf,
                           method=method, rmse=float(np.sqrt(np.mean((y - pred) ** 2))))


def _osc(t, A, a, w, ph, c):
    return A * np.exp(-a * t) * np.cos(w * t + ph) + c


def fit_second_order_decay(t, y, *, inertia: float | None = None, stiffness: float | None = None) -> SecondOrderDecay:
    """Fit a damped oscillation ``A e^{−ζω_n t} cos(ω_d t + φ) + c`` to a roll/pitch decay.

    Start values: ω_d from the zero crossings (or FFT peak), decay rate from the log decrement of
    successive peaks. Returns ζ, ω_n and the damping coefficient (see the module docstring).
    """
    t, y = _check(t, y, "second-order decay")
    yc = y - np.mean(y[-max(3, y.size // 10):])
    crossings = np.nonzero(np.diff(np.sign(yc)) != 0)[0]
    if crossings.size >= 3:
        wd0 = math.pi / float(np.mean(np.diff(t[crossings])))
    else:
        f = np.fft.rfftfreq(y.size, t[1] - t[0])
        wd0 = 2 * math.pi * f[1 + int(np.argmax(np.abs(np.fft.rfft(yc))[1:]))]
    peaks = [i for i in range(1, y.size - 1) if abs(yc[i]) >= abs(yc[i - 1]) and abs(yc[i]) >= abs(yc[i + 1])
             and abs(yc[i]) > 0.2 * np.max(np.abs(yc))]
    a0 = 0.05 * wd0
    if len(peaks) >= 2:
        amp = np.abs(yc[peaks])
        slope = np.polyfit(t[peaks], np.log(amp), 1)[0]
        a0 = max(-slope, 1e-4)
    A0 = float(np.max(np.abs(yc)))
    ph0 = 0.0 if yc[0] >= 0 else math.pi
    popt, pcov = optimize.curve_fit(_osc, t, y, p0=(A0, a0, wd0, ph0, float(y[-1])), maxfev=20000)
    A, a, wd, ph, c = (float(v) for v in popt)
    if A < 0:
        A, ph = -A, ph + math.pi
    wd = abs(wd)
    wn = math.sqrt(wd * wd + a * a)
    zeta = a / wn
    # delta method for ζ = a/√(a²+ω_d²), ω_n = √(a²+ω_d²)
    cov2 = pcov[np.ix_([1, 2], [1, 2])]
    gz = np.array([wd * wd / wn**3, -a * wd / wn**3])
    gw = np.array([a / wn, wd / wn])
    pred = _osc(t, *popt)
    nan = float("nan")
    # physical parameters by the delta method on (a, ω_d): b = 2aI; b = 2ak/ω_n²; I = k/ω_n² (ω_n² = a² + ω_d²)
    wn4 = wn**4

    def se(g):
        return float(math.sqrt(max(g @ cov2 @ g, 0.0)))

    phys = {}
    if inertia is not None:
        phys["damping_from_inertia_stderr"] = se(np.array([2 * inertia, 0.0]))
    if stiffness is not None:
        phys["damping_from_stiffness_stderr"] = se(np.array([2 * stiffness * (wd * wd - a * a) / wn4,
                                                             -4 * a * stiffness * wd / wn4]))
        phys["implied_inertia_stderr"] = se(np.array([-2 * stiffness * a / wn4, -2 * stiffness * wd / wn4]))
    return SecondOrderDecay(
        amplitude=A, zeta=zeta, omega_n=wn, omega_d=wd, phase=ph, offset=c,
        damping_from_inertia=2 * zeta * wn * inertia if inertia is not None else nan,
        damping_from_stiffness=2 * zeta * stiffness / wn if stiffness is not None else nan,
        implied_inertia=stiffness / wn**2 if stiffness is not None else nan,
        zeta_stderr=float(math.sqrt(max(gz @ cov2 @ gz, 0.0))),
        omega_n_stderr=float(math.sqrt(max(gw @ cov2 @ gw, 0.0))),
        method="curve_fit", rmse=float(np.sqrt(np.mean((y - pred) ** 2))), **phys,
    )


def curve_fit_runs(runs, order: int, given: dict[str, float]) -> list[FirstOrderDecay | SecondOrderDecay]:
    """The direct curve fit of every run: ``order`` 1 on channel ``velocity`` (``given["m"]`` turns the rate
    into damping), 2 on channel ``angle`` (``given`` holds ``I`` and/or ``k``)."""
    out = []
    for r in runs:
        if order == 1:
            r.require("velocity", "a first-order decay curve fit")
            out.append(fit_first_order_decay(r.time, r["velocity"], given["m"]))
        else:
            r.require("angle", "a second-order decay curve fit")
            out.append(fit_second_order_decay(r.time, r["angle"], inertia=given.get("I"), stiffness=given.get("k")))
    return out


def curve_fit_text(runs, fits, given: dict[str, float]) -> str:
    """A short report of :func:`curve_fit_runs`: physical parameters ± standard errors per run."""
    lines = [("direct decay curve fits; standard errors by the delta method, the given inertia/stiffness "
              f"({', '.join(f'{k} = {v:g}' for k, v in given.items())}) taken as exact:")]
    for r, f in zip(runs, fits):
        if isinstance(f, FirstOrderDecay):
            lines.append(f"  {r.name}: rate {f.rate:.5g} ± {f.rate_stderr:.2g} 1/s, time constant {f.time_constant:.4g} s, "
                         f"D = rate·m = {f.damping:.5g} ± {f.damping_stderr:.2g}, rmse {f.rmse:.3g}")
            continue
        lines.append(f"  {r.name}: zeta {f.zeta:.4g} ± {f.zeta_stderr:.2g}, omega_n {f.omega_n:.5g} ± "
                     f"{f.omega_n_stderr:.2g} rad/s, period {f.period:.4g} s, rmse {f.rmse:.3g} rad")
        if "I" in given:
            lines.append(f"      b = 2ζω_n·I = {f.damping_from_inertia:.5g} ± {f.damping_from_inertia_stderr:.2g}")
        if "k" in given:
            lines.append(f"      b = 2ζk/ω_n = {f.damping_from_stiffness:.5g} ± {f.damping_from_stiffness_stderr:.2g}; "
                         f"inertia implied by k and the period k/ω_n² = {f.implied_inertia:.5g} ± "
                         f"{f.implied_inertia_stderr:.2g}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """``python -m diffship.decay RUN.csv ... --model decay1 --fix m=VALUE`` (or ``decay2 --fix I=.. k=..``):
    the direct curve fits with standard errors of the damping (and inertia); exit 2 with one ``error:`` line."""
    import argparse
    import sys
    from pathlib import Path

    from .data import load_runs
    from .errors import DiffshipError
    from .params import parse_assignments

    p = argparse.ArgumentParser(prog="python -m diffship.decay", description="Direct free-decay curve fits: "
                                "decay1 x0·exp(−(D/m)t) on 'velocity', decay2 damped oscillation on 'angle'.")
    p.add_argument("runs", nargs="+", metavar="RUN.csv")
    p.add_argument("--model", default="decay2", choices=("decay1", "decay2"))
    p.add_argument("--fix", nargs="*", default=[], metavar="NAME=VALUE",
                   help="decay1: m (total inertia, rigid + added); decay2: I and/or k (restoring stiffness)")
    p.add_argument("--columns", nargs="*", default=[], metavar="NAME=COLUMN")
    p.add_argument("--degrees", nargs="*", default=[], metavar="COLUMN")
    p.add_argument("--out", default=None, metavar="DIR", help="write report.txt and decay.png here")
    args = p.parse_args(argv)
    try:
        given = parse_assignments(args.fix, "--fix")
        allowed = ("m",) if args.model == "decay1" else ("I", "k")
        bad = [n for n in given if n not in allowed]
        if bad or not given:
            raise DiffshipError(f"model {args.model} needs --fix {' and/or '.join(f'{n}=VALUE' for n in allowed)} "
                                f"({'the total inertia, rigid + added' if args.model == 'decay1' else 'inertia, stiffness'})"
                                + (f"; unknown: {', '.join(bad)}" if bad else ""))
        columns = dict(c.split("=", 1) for c in args.columns if "=" in c)
        runs = load_runs(args.runs, columns=columns or None, degrees=args.degrees)
        fits = curve_fit_runs(runs, 1 if args.model == "decay1" else 2, given)
    except (DiffshipError, RuntimeError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    text = curve_fit_text(runs, fits, given)
    print(text)
    if args.out:
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        (out / "report.txt").write_text(text + "\n")
        plot_curve_fits(runs, fits, out / "decay.png")
    return 0


def plot_curve_fits(runs, fits, path) -> None:
    """Measured decay and fitted curve, one panel per run (PNG)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(runs), 1, figsize=(7, 2.4 * len(runs)), squeeze=False)
    for ax, r, f in zip(axes[:, 0], runs, fits):
        t = np.asarray(r.time) - r.t0
        if isinstance(f, FirstOrderDecay):
            y, fit, lab = r["velocity"], f.x0 * np.exp(-f.rate * t), "velocity [SI]"
        else:
            y, fit, lab = r["angle"], _osc(t, f.amplitude, f.zeta * f.omega_n, f.omega_d, f.phase, f.offset), "angle [rad]"
        ax.plot(t, y, ".", ms=2, label=f"{r.name} measured")
        ax.plot(t, fit, lw=1.2, label="curve fit")
        ax.set_ylabel(lab, fontsize=8)
        ax.legend(fontsize=7)
    axes[-1, 0].set_xlabel("time from the first sample [s]")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def decay_run(model: Decay1 | Decay2, duration: float, dt: float, x0, *, noise: float = 0.0, seed: int = 0,
              name: str = "decay"):
    """A synthetic free-decay run of a decay model (τ = 0) with white noise on the outputs."""
    from .synthetic import simulate_run

    t = np.arange(0.0, duration + 0.5 * dt, dt)
    nz = {c: noise for c in model.output_names} if noise else "none"
    return simulate_run(model, t, {"tau": np.zeros_like(t)}, np.asarray(x0, dtype=np.float64), name=name, noise=nz,
                        seed=seed)


if __name__ == "__main__":
    from .cli_options import exit_now

    exit_now(main())
