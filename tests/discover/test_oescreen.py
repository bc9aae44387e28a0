"""The discovery compiles its all-terms programs while the base fit runs.

:func:`diffship.discover.oescreen.term_programs` builds the all-terms workspace and the ranking's simulation from
the base model *before* its fit. They are worth compiling only if they are the programs the discovery runs after
the fit: the same compile-cache keys, whatever values, noise scales and initial states the fit ends at.
"""

import types

import numpy as np
import pandas as pd

from diffship import compiled
from diffship.data import Run
from diffship.discover.oescreen import term_programs, term_workspace
from diffship.fit.problem import default_channels
from diffship.integrators import RK4
from diffship.models import Fossen3
from diffship.models.terms import with_terms
from diffship.initial import start_request
from diffship.metrics import start_channels
from diffship.simulate import simulation_request


def _runs():
    t = np.arange(0.0, 30.0 + 1e-9, 0.5)
    out = []
    for i in range(3):
        rng = np.random.default_rng(i)
        cols = {"time": t, "u": 1.5 + 0.1 * np.sin(0.2 * t), "v": 0.05 * np.sin(0.3 * t + i),
                "r": 0.05 * np.sin(0.25 * t), "psi": 0.2 * np.cos(0.25 * t), "x0": 1.5 * t, "y0": 0.1 * t,
                "tau_x": 40.0 + rng.normal(0.0, 1.0, t.size), "tau_y": np.zeros_like(t),
                "tau_z": 5.0 * np.sin(0.25 * t)}
        out.append(Run.from_dataframe(pd.DataFrame(cols), name=f"run{i}"))
    return out


def _keys(requests):
    return [compiled._key(*r) for r in requests]


def test_the_start_models_term_programs_are_the_fitted_discoverys():
    runs = _runs()
    train, val = runs[:2], runs[2:]
    base = Fossen3()
    spec = base.spec()
    terms = ["X_v_r", "N_r_r_r"]
    chans = default_channels(base, train)
    before = term_programs(base, spec, train, val, terms, chans, RK4())
    # the workspace's residuals and refits' solve, the all-terms simulation of the runs (one length), and its
    # initial-state estimates by the metrics' start rule on the training and on the held-out runs
    assert len(before) == 5
    # the fit's end: other values, noise scales and initial states
    start = spec.nudged({p.name: p.value for p in spec.params})[0]
    fitted = {n: 1.3 * start[n] - 0.01 for n in spec.free_names}
    values = {**{p.name: p.value for p in spec.params}, **fitted}
    res0 = types.SimpleNamespace(model=base.with_params(values), params=values, channels=chans,
                                 noise_std={c: 0.37 for c in chans}, channel_scales={},
                                 initial_states=tuple(np.full(len(base.state_names), 0.01) for _ in train),
                                 integrator=RK4())
    ws = term_workspace(res0, spec, train, terms)
    assert _keys(before[:2]) == _keys(ws.programs())
    full = with_terms(res0.model, terms).with_params({t: -50.0 for t in terms})
    assert _keys(before[2:3]) == _keys([simulation_request(full, val[0], np.full(len(full.state_names), 0.2), RK4())])
    assert _keys(before[3:]) == _keys([q for rs in (train, val)
                                       for q in start_request(full, rs, start_channels(full, rs, chans), integrator=RK4())])
    assert _keys(before[3:4]) == _keys(before[4:5])  # two training runs and one held-out run: one start-rule program
    # other refit options are another program: the comparison can fail
    assert _keys(term_workspace(res0, spec, train, terms, max_iter=61).programs()) != _keys(before[:2])


def test_the_final_fits_programs_are_known_before_it(monkeypatch):
    """A discovery compiles the final fit of each structure its polish reaches while the polish goes on
    (:meth:`diffship.fit.OutputError.programs`): they must be the programs that fit then compiles, whatever values
    the structure ends at, and another structure's must differ."""
    from diffship.discover.scaling import force_levels, term_spec
    from diffship.fit import OutputError, fit
    from diffship.fit import kernel as K

    seen = []
    real = K.compiled_many
    monkeypatch.setattr(K, "compiled_many", lambda reqs: (seen.extend(reqs), real(reqs))[1])
    runs = _runs()
    base = Fossen3()
    spec = base.spec().only_free(("Xu", "Yv", "Nr"))
    o = OutputError(integrator=RK4(), reference_priors=False, warmup=0.0, adaptive=False, max_steps=2)

    def problem(terms, scale):
        model = with_terms(base.with_params({"Xu": -20.0 * scale}), terms)
        return model, term_spec(model, spec.with_values({"Xu": -20.0 * scale}), runs, force_levels(runs, base))

    before = o.programs(*problem(("X_v_r", "N_r_r_r"), 1.0)[:1], runs, problem(("X_v_r", "N_r_r_r"), 1.0)[1])
    assert len(before) == 3  # the residuals, the solve and the noisy-input covariance term (tau_x is noisy here)
    model, cspec = problem(("X_v_r", "N_r_r_r"), 1.7)
    fit(model, runs, o, spec=cspec, n_starts=1, throw=False)
    assert set(_keys(before)) <= set(_keys(seen))
    other = o.programs(*problem(("X_v_r",), 1.0)[:1], runs, problem(("X_v_r",), 1.0)[1])
    assert not set(_keys(other)) & set(_keys(before))
