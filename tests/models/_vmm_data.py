"""Shared synthetic zigzag-like runs of the VMM reference ship (test helper)."""

import numpy as np

from diffship.models.vmm import U0_REF, approach_thrust
from diffship.synthetic import rudder_sequence, simulate_run

DEG = np.pi / 180


def vmm_runs(model, n_runs=2, duration=300.0, dt=0.5, noise="realistic", seed=0):
    """Open-loop alternating-rudder runs (10°–25°, rate 2.3°/s) with thrust steps of ±20–30 %."""
    T0 = approach_thrust(float(model.X0), float(model.XT), float(model.U0), float(model.L), float(model.rho))
    out = []
    for i in range(n_runs):
        t = np.arange(0.0, duration + dt / 2, dt)
        amp = [10, -20, 15, -25][i % 4] * DEG
        period = [60.0, 80.0, 70.0, 90.0][i % 4]
        delta = rudder_sequence(t, amp, period, rate=2.3 * DEG, start=5.0)
        thrust = T0 * (1 + [0.3, -0.3, 0.2, -0.2][i % 4] * ((t > 0.3 * duration) & (t < 0.75 * duration)))
        x0 = np.array([0.0, 0.0, 0.0, float(model.U0), 0.0, 0.0])
        out.append(simulate_run(model, t, {"delta": delta, "thrust": thrust}, x0, name=f"zigzag_{i}", noise=noise,
                                seed=100 * seed + i))
    return out


__all__ = ["vmm_runs", "U0_REF"]
