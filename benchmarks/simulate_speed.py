"""Simulation and Jacobian cost: fixed-step RK4 scan vs diffrax Tsit5, behind one interface.

Problem: the fossen3 USV (``diffship.synthetic.usv_truth``), 3 runs × 300 s at 10 Hz, force
inputs. Measures, for both solvers of :func:`diffship.simulate.simulate`: compile time, one
batched simulation (``jax.vmap`` over runs), and the forward-mode Jacobian of all outputs with
respect to the 16 parameters (what Levenberg–Marquardt needs).

    python -m benchmarks simulate_speed [--repeat 10]
"""

from __future__ import annotations

import argparse
import time

import jax
import jax.numpy as jnp


from benchmarks.common.fitapi import FLT_NONE, batch_of  # noqa: E402
from diffship.integrators import get_integrator  # noqa: E402
from diffship.simulate import simulate  # noqa: E402
from diffship.synthetic import usv_runs, usv_truth  # noqa: E402


def _time(fn, *args, repeat):
    t0 = time.perf_counter()
    jax.block_until_ready(fn(*args))
    first = time.perf_counter() - t0
    t0 = time.perf_counter()
    for _ in range(repeat):
        jax.block_until_ready(fn(*args))
    return first, (time.perf_counter() - t0) / repeat


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=10)
    args = ap.parse_args(argv)
    model = usv_truth()
    runs = usv_runs(3, 300.0, 0.1, noise="none")
    b = batch_of(model, runs, ("psi", "u", "v", "r"), FLT_NONE)
    ts, us, x0 = jnp.asarray(b.ts), jnp.asarray(b.us), jnp.asarray(b.x0)
    print(f"jax {jax.__version__}, devices {jax.devices()}; 3 runs × {b.ts.shape[1]} samples")
    print("| solver | compile+first sim [s] | sim (3 runs) [ms] | compile+first Jacobian [s] | Jacobian 16 params [ms] |")
    print("|---|---|---|---|---|")
    for solver in ("rk4", "tsit5"):
        sim = jax.jit(lambda m: jax.vmap(lambda t, u, x: simulate(m, t, u, x, get_integrator(solver)).ys)(ts, us, x0))
        c1, s1 = _time(sim, model, repeat=args.repeat)
        jac = jax.jit(jax.jacfwd(lambda th: jax.vmap(lambda t, u, x: simulate(model.with_params(th), t, u, x, get_integrator(solver)).ys)(ts, us, x0)))
        c2, s2 = _time(jac, model.theta(), repeat=max(2, args.repeat // 3))
        print(f"| {solver} | {c1:.2f} | {1e3 * s1:.1f} | {c2:.2f} | {1e3 * s2:.1f} |")
