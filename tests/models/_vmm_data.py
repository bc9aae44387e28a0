"""Shared synthetic zigzag-like runs of the VMM reference ship (test helper)."""

import numpy as np

from diffship.models import VMMLinear
from diffship.models.vmm import U0_REF, approach_thrust
from diffship.synthetic import rudder_sequence, simulate_run

DEG = np.pi / 180


#: Test truth factors: the reference ship's free derivatives scaled by DOF (surge and sway ×1.3,
#: yaw ×0.7), so that the model defaults (the reference ship) are 30 % off the truth.
TRUTH_FACTORS = {"X": 1.3, "Y": 1.3, "N": 0.7}


def vmm_truth(cls=VMMLinear):
    """A stable test ship that differs from ``cls()`` in every free derivative (``TRUTH_FACTORS``)."""
    ref = cls()
    free = ref.spec().free_names
    return ref.with_params({n: TRUTH_FACTORS[n[0]] * v for n, v in ref.param_values().items() if n in free})


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


__all__ = ["vmm_runs", "vmm_truth", "TRUTH_FACTORS", "U0_REF"]
