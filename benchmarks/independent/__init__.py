"""Independent hidden-effect scenario generator for judging ``diffship.diagnose``.

Written apart from diffship and sharing **no code** with it: plain NumPy/SciPy truth models,
its own fixed-step integrator, and its own implementation of every effect at the physics level
(``tests/diagnose/test_independent_generator.py`` parses these files and checks that nothing
from ``diffship`` is imported, and runs the generator in a process where ``diffship`` is never
loaded).

* :mod:`.vessels` — the truths: a 3-DOF USV (Fossen's matrix form, force inputs) and a
  first-order Nomoto ship steered by a real zigzag autopilot through a rate-limited steering
  gear;
* :mod:`.effects` — what is hidden in the truth: actuator lag/delay/rate limit on the actual
  actuator output, environmental offset forces, sensor biases, missing nonlinear damping
  forces, currents in the relative-velocity form, and out-of-family variants (rotating and
  ramped current, time-varying lag, wave-like disturbance, cubic damping);
* :mod:`.integrate` — a fine-step classical RK4 with the inputs evaluated at the sub-steps;
* :mod:`.scenarios` — the scenario grid (vessel × effect × size × seed, null cases) and
  :func:`generate`, returning plain arrays (``time``, measured ``channels``, ``clean`` outputs).
"""

from .scenarios import Scenario as Scenario
from .scenarios import generate as generate
from .scenarios import scenarios as scenarios

__all__ = ["Scenario", "generate", "scenarios"]
