"""The diagnosis compiles its workspace's programs while the base fit runs.

:func:`diffship.diagnose.diagnosis.workspace_programs` builds the all-effects workspace from the
base model *before* its fit. Its programs are useful only if they are the fitted workspace's own:
the same compile-cache keys, whatever values the fit ends at and whatever noise scales the
diagnosis then uses. And :func:`diffship.compiled.prefetch` must hand a later caller the program
it compiled, not compile it again.
"""

import numpy as np

import diffship  # noqa: F401
from diffship import compiled
from diffship.diagnose import DiagnoseOptions
from diffship.diagnose.diagnosis import diagnosis_channels, split_varying, workspace_programs
from diffship.diagnose.screen import Workspace
from diffship.integrators import Diffrax
from diffship.models import Nomoto2
from diffship.models.effects import library
from diffship.synthetic import nomoto_runs


def _runs():
    truth = Nomoto2(K=0.15, T1=12.0, T2=2.0, T3=4.0)
    return nomoto_runs(truth, n_runs=4, duration=40.0, dt=0.2, noise="realistic", seed=3)


def test_the_start_models_workspace_has_the_fitted_workspaces_programs():
    runs = _runs()
    train, val = runs[:2], runs[2:]
    model = Nomoto2()
    spec = model.spec()
    o = DiagnoseOptions()
    chans = diagnosis_channels(model, train)
    before = workspace_programs(model, spec, train, val, chans, o, Diffrax())
    # residuals and the refits' solve on the training runs, the start rule's one (residuals and Jacobian) and the
    # simulations of the base and of the workspace model on the held-out runs (one length)
    assert len(before) == 5
    # the workspace diagnose() builds after the fit: other values, other noise scales, fitted initial states
    fitted = {n: 1.3 * v + 0.01 for n, v in spec.nudged({p.name: p.value for p in spec.params})[0].items()}
    base = model.with_params(fitted)
    effs, _ = library(base, train, o.effect_names)
    effs = [e for e in effs if e.name != "rudder_offset"] if "delta0" in spec.free_names else effs
    effs = split_varying(effs)[0]  # the varying forms get a workspace of their own, when refitted
    ws = Workspace(base, spec.with_values(fitted), effs, train, chans, {c: 0.37 for c in chans},
                   x0_train=[np.full(len(base.state_names), 0.01) for _ in train], integrator=Diffrax(),
                   max_iter=o.max_iter, stall=o.stall)
    after = ws.programs(val)
    assert [compiled._key(*r) for r in before[:3]] == [compiled._key(*r) for r in after]
    # the held-out simulations a Validation runs: the base's and a refit's model (other values)
    from diffship.simulate import simulation_request
    sims = [simulation_request(m, val[0], np.full(len(m.state_names), 0.2), Diffrax())
            for m in (ws.base, ws.model_with({e.param_names[0]: 0.1 for e in effs[:1]}, fitted))]
    assert [compiled._key(*r) for r in before[3:]] == [compiled._key(*r) for r in sims]
    # a refit's own call asks for exactly the prefetched solve (its static options included)
    solve = [r for r in after if r[1] == "solve_coded"]
    assert solve and solve[0][3] == Workspace._solve_static(o.max_iter, o.stall)
    # and other options would be another program: the comparison can fail
    other = Workspace(base, spec.with_values(fitted), effs, train, chans, {c: 0.37 for c in chans},
                      integrator=Diffrax(), max_iter=o.max_iter + 1, stall=o.stall).programs(val)
    assert compiled._key(*other[1]) != compiled._key(*after[1])


def test_a_prefetched_program_is_the_one_a_later_caller_gets():
    runs = _runs()
    model = Nomoto2()
    o = DiagnoseOptions()
    chans = diagnosis_channels(model, runs[:2])
    reqs = workspace_programs(model, model.spec(), runs[:2], runs[2:], chans, o, Diffrax())[:1]  # the residuals
    compiled.clear()
    pre = compiled.prefetch(reqs, first_wait=0.0)
    pre.join(120)
    assert pre.compiled == 1 and not pre.failed
    fn, seconds = compiled.compiled(*reqs[0][:3], **reqs[0][3])
    assert seconds == 0.0  # found in the cache: not compiled again
    owner, name, args, _ = reqs[0]
    np.testing.assert_allclose(np.asarray(fn(*args)), np.asarray(getattr(owner, name)(*args)), rtol=0, atol=1e-12)
