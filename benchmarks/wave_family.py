"""The wave effect family beyond the benchmark grid: two measured cases.

* ``random_phase``: the independent USV with the generator's 6-s sway force / yaw moment
  (150 N, 600 N·m, no mean drift) at a **random phase per run** — the limitation of shared
  cos/sin amplitudes (they describe one phase relative to each run's start);
* ``ship``: the independent first-order Nomoto ship with a yaw disturbance
  F = ``--amp`` rad/s · sin(2πt/``--period``) in T ṙ + r = K(δ + δ0) + F (the Nomoto form of the
  family: a rudder-equivalent disturbance).

Truths come from :mod:`benchmarks.independent` (no diffship code); the grid's own ``wave``
scenario (phase locked to the run start, plus a mean drift force) is run by
``diagnosis_independent.py --only usv-wave``. Prints one summary per case; the numbers are in
``benchmarks/results/wave_family.md``.

Usage::

    python -m benchmarks wave_family --case random_phase --seed 1
    python -m benchmarks wave_family --case ship --amp 0.03 --period 8 --seed 1
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time

import numpy as np

import diffship  # noqa: F401  (float64)
from diffship.data import Run
from diffship.diagnose import diagnose
from diffship.models import Fossen3, Nomoto1

from benchmarks import independent  # noqa: E402  (the generator: no diffship inside)
from benchmarks.independent import effects as fx  # noqa: E402

SC = sys.modules["benchmarks.independent.scenarios"]  # the package exports a function of that name


@dataclasses.dataclass
class PhasedWave(fx.Wave):
    """The generator's wave oscillation with a phase offset [rad] (set per run)."""

    phase: float = 0.0

    def force(self, t, psi, nu_r):
        w = np.sin(2 * np.pi * t / self.period + self.phase)
        return np.array([0.0, self.F_osc * w, self.N_osc * w])


def _runs(gs):
    return [Run(g["name"], g["time"], g["channels"], {"source": "benchmarks.independent"}) for g in gs]


def generate(case: str, seed: int, amp: float, period: float) -> dict:
    usv0, ship0, sim0 = SC._usv_effect, SC._ship_effect, SC.simulate
    try:
        if case == "random_phase":
            SC._usv_effect = lambda label, k: PhasedWave(F_osc=150.0 * k, N_osc=600.0 * k, period=6.0)
            rng = np.random.default_rng(seed + 555)

            def sim(vessel, effs, t, **kw):
                for e in effs:
                    e.phase = float(rng.uniform(0.0, 2 * np.pi))
                return sim0(vessel, effs, t, **kw)

            SC.simulate = sim
            return independent.generate(independent.Scenario("usv", "wave", "out", "strong", seed))
        SC._ship_effect = lambda label, k: fx.Wave(N_osc=amp, period=period)
        return independent.generate(independent.Scenario("ship", "damping_rr", "in", "strong", seed))
    finally:
        SC._usv_effect, SC._ship_effect, SC.simulate = usv0, ship0, sim0


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--case", choices=("random_phase", "ship"), required=True)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--amp", type=float, default=0.03, help="ship: yaw disturbance amplitude F [rad/s]")
    p.add_argument("--period", type=float, default=8.0, help="ship: disturbance period [s]")
    p.add_argument("--verbose", action="store_true")
    a = p.parse_args(argv)
    g = generate(a.case, a.seed, a.amp, a.period)
    base = Fossen3() if a.case == "random_phase" else Nomoto1()
    t0 = time.perf_counter()
    d = diagnose(base, _runs(g["train"]), _runs(g["val"]), progress=print if a.verbose else None)
    wall = time.perf_counter() - t0
    pv = d.final_model.param_values()
    wave = next(r for r in d.ranking if r.effect == "wave")
    print(f"case {a.case} seed {a.seed}: selected {'+'.join(d.selected) or 'none'}; E {d.E_before:.3g} → {d.E_after:.3g}, "
          f"shrink {d.shrink:.2f}; wall {wall:.0f} s (shared machine)")
    print(f"wave: {wave.verdict}; single refit {wave.params} ± {wave.stderr}; validation gain "
          f"{100 * wave.validation_gain:.1f} %, runs improved {wave.runs_improved}")
    print("final:", {k: round(v, 6) for k, v in pv.items() if k in ("A_Yc", "A_Ys", "A_Nc", "A_Ns", "a_c", "a_s", "T_w", "delta_off")})
    print("\n".join(d.verdict))
