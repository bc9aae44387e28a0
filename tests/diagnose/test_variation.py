"""The time-variation check (:mod:`diffship.diagnose.variation`) refits a varying form only where
the constant effect leaves a structural gap on the held-out runs."""

from types import SimpleNamespace

from diffship.diagnose.variation import time_variation
from diffship.errors import FitError


def _search(E_const: float, gate: float = 1.05):
    calls = []

    def refit(names, starts, progress=None, base_start=None):
        calls.append(tuple(names))
        raise FitError("stub: the refit is not run in this test")

    ws = SimpleNamespace(effects=[SimpleNamespace(name="current"), SimpleNamespace(name="current_trend")], refit=refit)
    const = SimpleNamespace(score=SimpleNamespace(E=E_const),
                            refit=SimpleNamespace(values={"Vcx": 0.1, "Vcy": 0.2}, base_values={}),
                            judgement=SimpleNamespace(gain=0.9))
    return SimpleNamespace(ws=ws, has_gap=True, gate=gate), {"current": const}, calls


def test_no_varying_refit_when_the_constant_effect_is_under_the_gap_gate():
    said = []
    search, singles, calls = _search(E_const=1.01)
    assert time_variation(search, singles, ("current",), said.append) is None
    assert calls == []  # not refitted
    assert "under the gap gate" in said[-1] and "current" in said[-1]


def test_the_varying_form_is_refitted_when_a_gap_is_left():
    said = []
    search, singles, calls = _search(E_const=1.40)
    assert time_variation(search, singles, ("current",), said.append) is None  # the stub's refit fails
    assert calls == [("current_trend",)]
    assert "refit current_trend failed" in said[-1]


def test_the_varying_form_gets_a_workspace_of_its_own_only_when_it_is_refitted():
    """The all-effects workspace does not carry the varying forms (:func:`~diffship.diagnose.diagnosis.split_varying`):
    the check builds the form's own workspace, and only when the constant effect leaves a gap."""
    from diffship.diagnose.diagnosis import split_varying
    from diffship.models.effects import POSSIBLE_ONLY

    effs = [SimpleNamespace(name=n) for n in ("current", "current_trend", "actuator_lag", "lag_trend")]
    kept, varying = split_varying(effs)
    assert [e.name for e in kept] == ["current", "actuator_lag"] and set(varying) == set(POSSIBLE_ONLY)
    for E_const, built in ((1.01, []), (1.40, ["current_trend"])):
        made, calls = [], []

        def make(name):
            made.append(name)

            def refit(names, starts, progress=None, base_start=None):
                calls.append(tuple(names))
                raise FitError("stub: the refit is not run in this test")
            return SimpleNamespace(effects=[SimpleNamespace(name=name)], refit=refit), None
        search, singles, main_calls = _search(E_const)
        search.ws.effects = [SimpleNamespace(name="current")]  # the all-effects workspace: no varying form
        assert time_variation(search, singles, ("current",), lambda s: None,
                              varying={"current_trend": lambda: make("current_trend")}) is None
        assert made == built and calls == [tuple(built)] * len(built) and main_calls == []
