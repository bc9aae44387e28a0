"""The rudder offset each HSVA KVLCC2 zigzag asks of a fitted MMG: a symmetric rudder's evidence run by run.

A zigzag simulated with its measured rudder drifts in heading wherever the model turns more readily to one side
than the ship: the drift integrates the asymmetry. For every run this script finds the extra rudder offset
:math:`\\Delta\\delta_0` (added to the fit's ``delta0``) that minimises the whole-run heading RMSE of a simulation
from the run's measured first state, with every other parameter as fitted:

.. math:: \\Delta\\delta_0 = \\arg\\min_{d}\\ \\mathrm{RMSE}_t\\big(\\psi_{sim}(t;\\ \\delta_0 + d) - \\psi(t)\\big)

(a 0.25° grid over ±3°, refined by a parabola through the best three points). A model whose rudder is as
symmetric as the ship's asks the same offset of every run; an offset that changes with the rudder angle is an
asymmetry the model does not have. Beside it, the run's propeller loading
:math:`\\sqrt{1 + 8K_T/(\\pi J_P^2)} - 1` at its late speed (the second half's mean state; the MMG's own
propeller) and that speed.

Run from the repository root, on a fit file of the MMG (``python -m diffship.fit ... --model mmg --vessel
kvlcc2_model --rudder-sign port --out DIR`` writes ``DIR/fit.json``)::

    python -m benchmarks kvlcc2_rudder_offset DIR/fit.json

The HSVA data (not redistributable) are read from ``--data`` or ``$DIFFSHIP_SHARED_DATA``/``../shared/data``.
Writes ``results/kvlcc2_rudder_offset.md`` and ``.csv``.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import pandas as pd

from diffship.data import kvlcc2_runs, shared_data_dir
from diffship.fitfile import load_fit
from diffship.models.mmg import MMG
from diffship.simulate import initial_state, simulate_run

GRID_DEG = np.arange(-3.0, 3.0001, 0.25)


def _with_offset(model: MMG, delta0: float) -> MMG:
    return eqx.tree_at(lambda m: m.delta0, model, jnp.asarray(delta0, dtype=jnp.float64))


def heading_rmse(model: MMG, run, x0) -> float:
    """Whole-run heading RMSE [rad] of a simulation from ``x0`` with the measured inputs."""
    sim = simulate_run(model, run, x0)
    psi = np.unwrap(np.asarray(sim.xs)[:, model.state_names.index("psi")])
    e = psi - np.unwrap(np.asarray(run["psi"]))
    return float(np.sqrt(np.mean(e ** 2))) if bool(np.all(np.asarray(sim.valid))) else math.inf


def best_offset(model: MMG, run) -> tuple[float, float, float]:
    """``(offset [rad], RMSE there [rad], RMSE at the fitted offset [rad])`` (module docstring)."""
    x0, d0 = initial_state(model, run), float(model.delta0)
    grid = np.radians(GRID_DEG)
    costs = np.array([heading_rmse(_with_offset(model, d0 + d), run, x0) for d in grid])
    base = costs[int(np.argmin(np.abs(grid)))]
    i = int(np.clip(np.argmin(costs), 1, len(grid) - 2))
    c_m, c_0, c_p = costs[i - 1:i + 2]
    h, den = grid[1] - grid[0], c_m - 2 * c_0 + c_p
    d = grid[i] + (0.5 * h * (c_m - c_p) / den if np.isfinite(den) and den > 0 else 0.0)
    return d, heading_rmse(_with_offset(model, d0 + d), run, x0), base


def loading(model: MMG, run) -> tuple[float, float]:
    """``(propeller loading, speed [m/s])`` at the second half's mean state (module docstring)."""
    half = slice(len(run.time) // 2, None)
    u, v, r, n = (float(np.mean(np.asarray(run[c])[half])) for c in ("u", "v", "r", "n"))
    return float(model.propeller_loading(u, v, r, n)), math.hypot(u, v)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("fit", help="fit file of the MMG on the HSVA zigzags (fit.json)")
    ap.add_argument("--data", default=None, help="folder with kvlcc2_hsva/ (default: the shared data)")
    ap.add_argument("--out", default=str(Path(__file__).parent / "results"))
    args = ap.parse_args(argv)
    root = Path(args.data) if args.data else shared_data_dir()
    if root is None or not (root / "kvlcc2_hsva").is_dir():
        print("kvlcc2_rudder_offset: the HSVA KVLCC2 data are not here (--data DIR or $DIFFSHIP_SHARED_DATA "
              "naming the folder that holds kvlcc2_hsva/); nothing run", file=sys.stderr)
        return 2
    fit = load_fit(args.fit)
    if not isinstance(fit.model, MMG):
        print(f"kvlcc2_rudder_offset: {args.fit} is a fit of {fit.model.name}, not of the MMG", file=sys.stderr)
        return 2
    key = lambda name: str(name).split("KVLCC2_")[-1]  # noqa: E731  (file stem or loader name: Z_<rudder>_<switch>)
    trained = {key(d.get("run")) for d in fit.data}
    rows, t0 = [], time.perf_counter()
    for run in kvlcc2_runs(root / "kvlcc2_hsva"):
        d, rmse, base = best_offset(fit.model, run)
        load, speed = loading(fit.model, run)
        rows.append(dict(run=key(run.name), training=key(run.name) in trained,
                         rudder_deg=float(np.degrees(np.max(np.abs(np.asarray(run["delta"]))))),
                         late_speed=speed, loading=load, rmse_fitted_deg=math.degrees(base),
                         offset_deg=math.degrees(d), rmse_offset_deg=math.degrees(rmse)))
        print(f"{rows[-1]['run']:10s} |δ| {rows[-1]['rudder_deg']:5.1f}°  loading {load:4.2f}  extra offset "
              f"{math.degrees(d):+6.2f}°  heading RMSE {math.degrees(base):6.2f}° → {math.degrees(rmse):5.2f}°",
              flush=True)
    df = pd.DataFrame(rows).sort_values(["rudder_deg", "run"])
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    df.to_csv(out / "kvlcc2_rudder_offset.csv", index=False)
    lines = [
        "# The rudder offset each HSVA KVLCC2 zigzag asks of the fitted MMG",
        "",
        f"`python -m benchmarks kvlcc2_rudder_offset FIT.json` ({time.perf_counter() - t0:.0f} s), FIT.json a fit of "
        f"{fit.model.name} by {fit.method.replace('_', ' ')} on {', '.join(sorted(trained))} "
        f"({len(fit.free)} free parameters, {fit.status}; "
        "`benchmarks/kvlcc2_rudder_offset.py`): the extra rudder offset that minimises each run's whole-run heading "
        "RMSE, every other parameter as fitted, from the run's measured first state. The fit's own rudder offset: "
        f"δ0 = {math.degrees(float(fit.model.delta0)):+.2f}°.",
        "",
        "| run | trained on | largest rudder [deg] | late speed [m/s] | propeller loading "
        "| heading RMSE, as fitted [deg] | extra offset [deg] | heading RMSE with it [deg] |",
        "|---|---|---|---|---|---|---|---|",
    ]
    lines += [f"| {r.run} | {'yes' if r.training else 'no'} | {r.rudder_deg:.1f} | {r.late_speed:.3f} "
              f"| {r.loading:.2f} | {r.rmse_fitted_deg:.2f} | {r.offset_deg:+.2f} | {r.rmse_offset_deg:.2f} |"
              for r in df.itertuples()]
    (out / "kvlcc2_rudder_offset.md").write_text("\n".join(lines) + "\n")
    print(f"written: {out / 'kvlcc2_rudder_offset.md'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
