"""Helpers shared by the benchmarks.

* :mod:`.fitapi` — every call from the benchmarks into diffship's fitting API (one place to edit when
  its signatures change);
* :mod:`.peers` — the NumPy/SciPy peers (scipy ``least_squares`` over NumPy RK4, NumPy OLS on inverse
  dynamics, STLSQ/SINDy);
* :mod:`.casadi_peer` — diffship's Fossen 3-DOF output-error problem written with CasADi (a standalone
  script too: the timing benchmarks run it as a process);
* :mod:`.injections` — effects injected exactly into measured runs (a uniform water drift);
* :mod:`.timing` — machine load, medians, timed processes, the git commit and the environment line of
  a report, the time-bounded scipy peer.
"""
