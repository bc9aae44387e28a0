"""Coverage of output-error 95 % intervals with measured (noisy) inputs and outputs.

Question: do diffship's standard errors hold when the inputs the fit
simulates with are measurements — rudder angle with 0.05–0.1° noise, thrust with 1 % noise —
and the outputs carry sensor noise? Residuals are then coloured (the model's response to the
input noise), and ``σ̂²(JᵀJ)⁻¹`` assumes white ones.

Truth simulators are written here in plain NumPy (their own equations, RK4 with 10 sub-steps
per sample on a 10× finer input grid) and import nothing from ``diffship.models`` or
``diffship.simulate``; the fitter only sees sampled CSV-like runs:

* ``vmm``: the polynomial ``vmm_simple`` model (prime system, instantaneous U) of a Mariner-like
  cargo ship at full scale (L = 160.93 m, U0 = 7.72 m/s), 3 open-loop alternating-rudder runs
  (10–25°, 2.3°/s) with ±20–30 % thrust steps, 300 s at 2 Hz; 16 free derivatives; sensor noise
  heading 0.1°, yaw rate 0.05°/s, u and v 0.01 m/s (model-test levels);
* ``usv``: the seed-002 USV in Fossen's 3-DOF form (with added masses), 3 runs of 200 s at
  10 Hz of jet thrust steps and nozzle zigzags; 10 free parameters; GNSS velocity 0.05 m/s,
  heading 0.5°, gyro 0.2°/s.

Input noise, white per sample: rudder/nozzle angle σ = 0.05° + 0.05°·U(0, 1) per seed, thrust
1 % (multiplicative). The excitation is the same for every seed (a fixed design); only noise
changes, so coverage is over noise realisations. Each seed is fitted once
(:func:`diffship.fit.fit_output_error`, start ×0.8/×1.2 of the truth, initial ψ, u, v, r
estimated per run, no reference priors: the intervals of the data alone); at the optimum the residual and Jacobian are evaluated by the same kernel and
the covariance is computed three ways from the same ``J`` and ``r``: ``white`` (σ̂²(JᵀJ)⁻¹),
``hac`` (Newey–West sandwich, the default where residuals are not white) and ``block``
(linearised moving-block bootstrap). Reported: the share of |θ̂ − θ| ≤ 1.96·SE over parameters ×
seeds (95 % intervals: honest ≈ 95 %, target 90–99 %), per parameter, the lag-1
autocorrelation of the residuals, and seconds per fit.

    python -m benchmarks coverage [--seeds 50] [--cases vmm usv] [--quick]

Writes ``benchmarks/results/coverage.md`` and ``coverage.csv`` (``--quick``: 3 seeds, ``*_quick``).
"""

from __future__ import annotations

import argparse
import csv
import os
import time
from pathlib import Path

import numpy as np


DEG = np.pi / 180.0
KINDS = ("white", "hac", "block", "white+inputs", "hac+inputs")
SUB = 10  # truth: sub-steps (and input-grid refinement) per sample


# ---------------------------------------------------------------- NumPy truth: polynomial model
E5 = 1e-5
L, RHO, U0 = 160.93, 1025.0, 7.7175
H3 = 0.5 * RHO * L**3
VMM_TRUE = {k: v * E5 for k, v in dict(
    X0=-100.0, Xu=-184.0, Xvv=-899.0, Xrr=36.4, Xvr=0.0, Xdd=-95.0,
    Yv=-1160.0, Yr=299.0, Yd=-278.0, Yvvv=-8078.0, Yvvr=15356.0,
    Nv=-264.0, Nr=-184.4, Nd=139.0, Nvvv=1636.0, Nvvr=-5483.0).items()}  # fmt: skip
VMM_FIXED = dict(m=798 * E5 * H3, xG=-0.023 * L, Iz=(39.2 + 798 * 0.023**2) * E5 * 0.5 * RHO * L**5, XT=0.8,
                 Xudot=-42 * E5, Yvdot=-748 * E5, Yrdot=-9.354 * E5, Nvdot=4.646 * E5, Nrdot=-43.8 * E5)


def vmm_rhs(x, inp, p):
    """ẋ of the 3-DOF polynomial model; x = (x0, y0, ψ, u, v, r), inp = (δ, T)."""
    psi, u, v, r = x[2], x[3], x[4], x[5]
    d, T = inp
    U = np.sqrt(u * u + v * v + 1e-6)
    q = 0.5 * RHO * L**2 * U**2
    du, vp, rp = (u - U0) / U, v / U, r * L / U
    Xp = (p["X0"] + p["Xu"] * du + p["Xvv"] * vp**2 + p["Xrr"] * rp**2 + p["Xvr"] * vp * rp + p["Xdd"] * d**2
          + p["XT"] * T / q)
    Yp = p["Yv"] * vp + p["Yr"] * rp + p["Yd"] * d + p["Yvvv"] * vp**3 + p["Yvvr"] * vp**2 * rp
    Np = p["Nv"] * vp + p["Nr"] * rp + p["Nd"] * d + p["Nvvv"] * vp**3 + p["Nvvr"] * vp**2 * rp
    m, xG = p["m"], p["xG"]
    F = np.array([q * Xp + m * (v * r + xG * r * r), q * Yp - m * u * r, q * L * Np - m * xG * u * r])
    h = 0.5 * RHO
    M = np.array([[m - p["Xudot"] * h * L**3, 0.0, 0.0],
                  [0.0, m - p["Yvdot"] * h * L**3, m * xG - p["Yrdot"] * h * L**4],
                  [0.0, m * xG - p["Nvdot"] * h * L**4, p["Iz"] - p["Nrdot"] * h * L**5]])
    acc = np.linalg.solve(M, F)
    return np.array([u * np.cos(psi) - v * np.sin(psi), u * np.sin(psi) + v * np.cos(psi), r, *acc])


def vmm_runs_true(dt=0.5, duration=300.0):
    """Three open-loop alternating-rudder runs with thrust steps: (t, δ, T, states) each."""
    T0 = -VMM_TRUE["X0"] * 0.5 * RHO * L**2 * U0**2 / VMM_FIXED["XT"]
    p = {**VMM_TRUE, **VMM_FIXED}
    out = []
    for i, (amp, period, step) in enumerate(((10.0, 60.0, 0.3), (-20.0, 80.0, -0.3), (25.0, 90.0, 0.2))):
        tf = np.arange(0.0, duration + dt / (2 * SUB), dt / SUB)
        target = np.where(tf < 5.0, 0.0, amp * DEG * np.sign(np.sin(np.pi * (tf - 5.0) / (period / 2) + 1e-9)))
        delta = np.zeros_like(tf)
        for k in range(1, tf.size):  # rudder rate 2.3°/s
            delta[k] = delta[k - 1] + np.clip(target[k] - delta[k - 1], -2.3 * DEG * dt / SUB, 2.3 * DEG * dt / SUB)
        thrust = T0 * (1 + step * ((tf > 0.3 * duration) & (tf < 0.75 * duration)))
        thrust = np.convolve(np.concatenate([np.full(20, thrust[0]), thrust]), np.ones(20) / 20, "valid")[1:]
        xs = rk4(vmm_rhs, np.array([0.0, 0.0, 0.0, U0, 0.0, 0.0]), np.stack([delta, thrust], 1), dt / SUB, p)
        out.append((tf[::SUB], delta[::SUB], thrust[::SUB], xs[::SUB]))
    return out


# ---------------------------------------------------------------- NumPy truth: 3-DOF USV (Fossen)
USV_TRUE = dict(Xudot=-400.0, Yvdot=-600.0, Nrdot=-8000.0, Xu=-70.0, Yv=-300.0, Nv=1700.0, Nr=-1800.0,
                Xuu=-320.0, Yvv=-2800.0, Nrr=-2400.0)
USV_FIXED = dict(m=4935.14, Iz=20928.0, xg=0.0, Yrdot=0.0, Nvdot=0.0, Yr=0.0)


def usv_rhs(x, tau, p):
    """ẋ of M ν̇ + C(ν)ν + D(ν)ν = τ (Fossen 2021, eqs. 6.42/6.57/6.60) with η̇ = R(ψ)ν."""
    psi, u, v, r = x[2], x[3], x[4], x[5]
    m, xg = p["m"], p["xg"]
    a = m * (xg * r + v) - p["Yvdot"] * v - 0.5 * (p["Nvdot"] + p["Yrdot"]) * r
    b = (m - p["Xudot"]) * u
    C = np.array([-a * r, b * r, a * u - b * v])
    D = -np.array([(p["Xu"] + p["Xuu"] * abs(u)) * u, (p["Yv"] + p["Yvv"] * abs(v)) * v + p["Yr"] * r,
                   p["Nv"] * v + (p["Nr"] + p["Nrr"] * abs(r)) * r])
    M = np.array([[m - p["Xudot"], 0, 0], [0, m - p["Yvdot"], m * xg - p["Yrdot"]],
                  [0, m * xg - p["Nvdot"], p["Iz"] - p["Nrdot"]]])
    acc = np.linalg.solve(M, tau - C - D)
    return np.array([u * np.cos(psi) - v * np.sin(psi), u * np.sin(psi) + v * np.cos(psi), r, *acc])


def _levels(rng, t, hold, lo, hi, ramp=2.0):
    dt = t[1] - t[0]
    k = max(1, int(round(hold / dt)))
    sig = np.repeat(rng.uniform(lo, hi, size=t.size // k + 2), k)[: t.size]
    w = max(1, int(round(ramp / dt)))
    return np.convolve(np.concatenate([np.full(w, sig[0]), sig]), np.ones(w) / w, mode="valid")[1 : t.size + 1]


def usv_runs_true(dt=0.1, duration=200.0):
    """Three runs of jet thrust steps (1.5–6 kN, 40 s) and nozzle zigzags (±20°, 12 s)."""
    p = {**USV_TRUE, **USV_FIXED}
    out = []
    for i in range(3):
        rng = np.random.default_rng(500 + i)
        tf = np.arange(0.0, duration + dt / (2 * SUB), dt / SUB)
        thrust = _levels(rng, tf, 40.0, 1500.0, 6000.0)
        nozzle = _levels(rng, tf, 12.0, -20 * DEG, 20 * DEG)
        tau = np.stack([thrust * np.cos(nozzle), thrust * np.sin(nozzle), -3.82 * thrust * np.sin(nozzle)], 1)
        xs = rk4(usv_rhs, np.array([0.0, 0.0, 0.0, 2.0, 0.0, 0.0]), tau, dt / SUB, p)
        out.append((tf[::SUB], nozzle[::SUB], thrust[::SUB], xs[::SUB]))
    return out


def rk4(rhs, x0, inputs, h, p):
    """Classical RK4 on the fine grid, inputs linear between fine samples."""
    xs = np.empty((inputs.shape[0], x0.size))
    xs[0] = x0
    x = x0
    for k in range(inputs.shape[0] - 1):
        u0, u1 = inputs[k], inputs[k + 1]
        um = 0.5 * (u0 + u1)
        k1 = rhs(x, u0, p)
        k2 = rhs(x + 0.5 * h * k1, um, p)
        k3 = rhs(x + 0.5 * h * k2, um, p)
        k4 = rhs(x + h * k3, u1, p)
        x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        xs[k + 1] = x
    return xs


# ---------------------------------------------------------------- noisy measurements -> diffship
def measured_runs(case, truth_runs, seed):
    """diffship Runs with sensor noise on the outputs and noise on the measured inputs."""
    from diffship.data import Run

    rng = np.random.default_rng(seed)
    angle_sd = (0.05 + 0.05 * rng.uniform()) * DEG
    out_sd = ({"psi": 0.1 * DEG, "u": 0.01, "v": 0.01, "r": 0.05 * DEG} if case == "vmm"
              else {"psi": 0.5 * DEG, "u": 0.05, "v": 0.05, "r": 0.2 * DEG})
    runs = []
    for i, (t, angle, thrust, xs) in enumerate(truth_runs):
        n = t.size
        ch = {c: xs[:, j] + rng.normal(0.0, out_sd[c], n) for j, c in ((2, "psi"), (3, "u"), (4, "v"), (5, "r"))}
        a_m = angle + rng.normal(0.0, angle_sd, n)
        T_m = thrust * (1 + 0.01 * rng.normal(size=n))
        if case == "vmm":
            ch.update(delta=a_m, thrust=T_m)
        else:
            ch.update(tau_x=T_m * np.cos(a_m), tau_y=T_m * np.sin(a_m), tau_z=-3.82 * T_m * np.sin(a_m))
        runs.append(Run(f"{case}_{i}", t, ch, {"source": "benchmarks/coverage.py"}))
    return runs, angle_sd


def draw_priors(truth, names, rel, seed):
    """Gaussian priors whose means are drawn around the truth: μ = θ + rel·|θ|·N(0, 1), sd = rel·|θ|. With
    the truth a draw from its prior, honest posterior 95 % intervals still cover 95 %; intervals that count
    the same information twice (prior, input-noise term, effective-sample weighting) would cover more
    (too wide) or less (too narrow)."""
    from diffship.fit.priors import Prior, Priors

    rng = np.random.default_rng(50_000 + seed)
    return Priors({n: Prior(mean=truth[n] + rel * abs(truth[n]) * rng.normal(), sd=rel * abs(truth[n]),
                            source=f"drawn around the truth, rel {rel}") for n in names if truth[n] != 0.0},
                  source="benchmark")  # a coefficient whose truth is 0 gets no (relative) prior


def fit_and_covariances(case, runs, prior_rel=None, seed=0):
    """One output-error fit; standard errors of the free parameters from white, HAC and block. With
    ``prior_rel``, a MAP fit under :func:`draw_priors` (only the reported covariance includes the priors)."""
    from diffship.fit import OutputErrorOptions, fit_output_error
    from diffship.fit.covariance import covariance
    from diffship.fit.input_noise import measured_input_meat
    from diffship.fit.kernel import Kernel, kernel_data
    from diffship.fit.output_error import x0_scales
    from diffship.fit.problem import make_batch
    from diffship.models import get_model

    truth = VMM_TRUE if case == "vmm" else USV_TRUE
    model = get_model("vmm_simple" if case == "vmm" else "fossen3")
    fixed = VMM_FIXED if case == "vmm" else USV_FIXED
    spec = model.spec().fix({k: v for k, v in fixed.items() if k in model.param_names})
    spec = spec.with_values({n: truth[n] * (0.8 if i % 2 else 1.2) for i, n in enumerate(spec.free_names)})
    est = ("psi", "u", "v", "r")
    priors = draw_priors(truth, spec.free_names, prior_rel, seed) if prior_rel else None
    opts = OutputErrorOptions(estimate_x0=est, reference_priors=False, priors=priors)  # no reference priors
    t0 = time.perf_counter()
    res = fit_output_error(model, runs, spec=spec, channels=("psi", "u", "v", "r"), options=opts)
    wall = time.perf_counter() - t0
    # the same kernel at the optimum: initial states as fitted, offsets zero
    batch = make_batch(model, runs, ("psi", "u", "v", "r"), opts.flt)
    kernel = Kernel(spec=spec.structural(), out_idx=tuple(model.output_names.index(c) for c in batch.channels),
                    angle=tuple(c in model.angle_outputs for c in batch.channels),
                    x0_idx=tuple(model.state_names.index(s) for s in est), integrator=opts.integrator)
    scales = np.array([res.channel_scales[c] for c in batch.channels])
    x0 = np.stack(res.initial_states)
    data = kernel_data(model.with_params(res.params), batch.ts, batch.us, batch.ys, batch.mask, x0, scales,
                       x0_scale=x0_scales(model, batch, est))
    fspec = spec.with_values({n: res.params[n] for n in spec.free_names})
    z = np.concatenate([fspec.to_z(fspec.values()), np.zeros(len(est) * len(runs))])
    r = np.asarray(kernel.call("residuals", z, data))
    J = np.asarray(kernel.call("jacobian", z, data))
    n_p = len(spec.free_names)
    dth = fspec.dtheta_dz(z[:n_p])
    meat, _, _ = measured_input_meat(kernel, z, data, J, batch.mask, model.input_names)
    ses, lag1 = {}, None
    for kind in KINDS:
        c = covariance(J, r, dof=batch.n_residuals - J.shape[1], kind=kind.split("+")[0], mask=batch.mask,
                       n_channels=len(batch.channels), input_meat=meat if kind.endswith("+inputs") else None)
        ses[kind] = np.sqrt(np.diag(c.matrix)[:n_p]) * np.abs(dth)
        lag1 = c.whiteness.lag1
    return res, ses, lag1, wall


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=50)
    ap.add_argument("--cases", nargs="*", default=["vmm", "usv"])
    ap.add_argument("--quick", action="store_true", help="3 seeds, files *_quick")
    ap.add_argument("--out", default=str(Path(__file__).parent / "results"))
    ap.add_argument("--prior-rel", type=float, default=None, metavar="REL",
                    help="MAP fits under Gaussian priors of relative sd REL with means drawn around the truth "
                         "(draw_priors): does the reported covariance double-count? Files *_priorREL")
    args = ap.parse_args(argv)
    seeds = 3 if args.quick else args.seeds
    tag = ("_quick" if args.quick else "") + (f"_prior{args.prior_rel:g}" if args.prior_rel else "")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    load0 = os.getloadavg()
    t_all = time.perf_counter()
    rows = []
    summary = {}
    for case in args.cases:
        t0 = time.perf_counter()
        truth_runs = vmm_runs_true() if case == "vmm" else usv_runs_true()
        t_truth = time.perf_counter() - t0
        truth = VMM_TRUE if case == "vmm" else USV_TRUE
        lag1s, walls, conv, default_kind = [], [], [], []
        for s in range(seeds):
            runs, angle_sd = measured_runs(case, truth_runs, 1000 + s)
            res, ses, lag1, wall = fit_and_covariances(case, runs, args.prior_rel, s)
            walls.append(wall)
            conv.append(res.converged)
            lag1s.append(lag1)
            default_kind.append(res.info.get("covariance", "?"))
            for j, n in enumerate(res.free):
                row = dict(case=case, seed=s, param=n, truth=truth[n], estimate=res.params[n],
                           angle_noise_deg=angle_sd / DEG, converged=res.converged, default=res.info.get("covariance"),
                           fit_wall_s=wall)
                for kind, se in ses.items():
                    row[f"se_{kind}"] = float(se[j])
                    row[f"z_{kind}"] = float((res.params[n] - truth[n]) / se[j])
                row["se_reported"] = res.stderr[n]
                rows.append(row)
            zs = {k: max(abs(r[f"z_{k}"]) for r in rows[-len(res.free):]) for k in ses}
            print(f"{case} seed {s}: {wall:.1f} s, converged {res.converged}, default {default_kind[-1]}, "
                  f"max|z| " + ", ".join(f"{k} {v:.2f}" for k, v in zs.items()), flush=True)
        summary[case] = dict(lag1=np.array(lag1s), walls=walls, conv=conv, kinds=default_kind, t_truth=t_truth)
    with open(out / f"coverage{tag}.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    note = (f"MAP fits under priors of relative sd {args.prior_rel:g} with means drawn around the truth (`--prior-rel`, "
            "`draw_priors`): only the *reported* column includes the priors; the others are the data-only "
            "covariances at the MAP estimate." if args.prior_rel else "")
    write_report(out / f"coverage{tag}.md", rows, summary, seeds, load0, time.perf_counter() - t_all, note)


def write_report(path, rows, summary, seeds, load0, total_s, note=""):
    lines = [f"# Coverage of output-error 95 % intervals with input and output noise ({seeds} seeds)", "",
             "Generated by `benchmarks/coverage.py` (see its docstring for the problem). Truth simulators in plain "
             "NumPy in the benchmark; diffship fits the noisy measured inputs and outputs. Coverage = share of "
             "(parameter, seed) pairs with |θ̂ − θ| ≤ 1.96·SE; honest 95 % intervals give ≈ 95 % (target 90–99 %). "
             f"Machine: 2 shared CPUs, load {load0[0]:.2f} at start, {os.getloadavg()[0]:.2f} at end; total "
             f"{total_s / 60:.1f} min (timings disturbed by other jobs)." + (f" {note}" if note else ""), "",
             "| case | seeds | converged | residual lag-1 autocorr. (median, max) | default covariance chosen | "
             "white | HAC | block bootstrap | white + inputs (EIV) | HAC + inputs (EIV) | reported (default) | "
             "SE ratio default/white (median) | s per fit |",
             "|---|---:|---:|---|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for case, s in summary.items():
        rr = [r for r in rows if r["case"] == case]

        def cov(k, rr=rr):
            return np.mean([abs(r[f"z_{k}"]) <= 1.96 for r in rr])

        rep = np.mean([abs(r["estimate"] - r["truth"]) <= 1.96 * r["se_reported"] for r in rr])
        ratio = np.median([r["se_reported"] / r["se_white"] for r in rr])
        kinds = {k: s["kinds"].count(k) for k in set(s["kinds"])}
        lines.append(f"| {case} | {seeds} | {np.mean(s['conv']):.0%} | {np.nanmedian(s['lag1']):.2f}, "
                     f"{np.nanmax(s['lag1']):.2f} | {', '.join(f'{k} ×{v}' for k, v in kinds.items())} | "
                     f"{cov('white'):.1%} | {cov('hac'):.1%} | {cov('block'):.1%} | {cov('white+inputs'):.1%} | "
                     f"{cov('hac+inputs'):.1%} | **{rep:.1%}** | {ratio:.2f} | "
                     f"{np.median(s['walls']):.1f} |")
    for case in summary:
        rr = [r for r in rows if r["case"] == case]
        names = list(dict.fromkeys(r["param"] for r in rr))
        lines += ["", f"## {case}: per parameter", "",
                  "| param | truth | RMS rel. error | white | HAC | block | white+inputs | HAC+inputs | reported | "
                  "max abs z (reported) | median SE reported/white |", "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
        for n in names:
            pr = [r for r in rr if r["param"] == n]
            t = pr[0]["truth"]
            rel = np.sqrt(np.mean([((r["estimate"] - t) / (abs(t) or 1e-5)) ** 2 for r in pr]))
            lines.append(f"| {n} | {t:.4g} | {rel:.2%} | "
                         + " | ".join(f"{np.mean([abs(r[f'z_{k}']) <= 1.96 for r in pr]):.0%}"
                                      for k in KINDS)
                         + f" | {np.mean([abs(r['estimate'] - t) <= 1.96 * r['se_reported'] for r in pr]):.0%}"
                         + f" | {max(abs(r['estimate'] - t) / r['se_reported'] for r in pr):.2f} | "
                         f"{np.median([r['se_reported'] / r['se_white'] for r in pr]):.2f} |")
    Path(path).write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
