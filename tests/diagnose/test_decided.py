"""Decided early (:mod:`diffship.diagnose.decided`, :meth:`diffship.diagnose.which.Search.refit_singles`):
when the first candidate by screening rank passes the rule and alone brings the held-out E under the
gap gate, the candidates screened far below it are not refitted — and only then (no simulation:
canned refits and scores)."""

import threading
from types import SimpleNamespace

import pytest

import diffship  # noqa: F401
from diffship.diagnose import DiagnoseOptions, make_effect
from diffship.diagnose.screen import RefitResult
from diffship.diagnose.verdict import rank
from diffship.diagnose.which import Search
from diffship.errors import DataError
from diffship.models import Fossen3

NAMES = ("current", "heading_bias", "damping_rr", "input_delay")
#: screened shares f_k: heading_bias 0.06 is above 5 % of the current's 0.7 (0.035), the others below
SHARES = {"current": 0.7, "heading_bias": 0.06, "damping_rr": 0.0004, "input_delay": 0.002}
GATE = 1.1


def _score(E):
    return SimpleNamespace(E=E, E_runs={"a": E, "b": E})


class _Canned(Search):
    """A search whose refits return given validation errors (and record when they ran)."""

    def __init__(self, E_after, options=DiagnoseOptions()):
        effs = [make_effect(Fossen3(), n) for n in NAMES]
        super().__init__(SimpleNamespace(effects=effs), None, None, options, lambda m: None, gate=GATE)
        self.E_after, self.calls, self._lock = E_after, [], threading.Lock()
        self.effs = {e.name: e for e in effs}

    def single_starts(self, name):
        return [self.effs[name].null()]

    def _refit(self, names, starts, base_start=None):
        (n,) = names
        with self._lock:
            self.calls.append(n)
        e = self.effs[n]
        # a fitted value far from the null with a small standard error: significant and relevant
        vals = {k: v + 10.0 * max(e.MIN_RELEVANT.get(k, 0.0), 1.0) for k, v in e.null().items()}
        rf = RefitResult((n,), vals, {k: 1e-3 for k in vals}, {}, 1.0, 10, 0.1, True)
        return rf, _score(self.E_after[n])


def _run(search, E_ref):
    reference = lambda extras: _score(E_ref)  # noqa: E731 — the reference's score once the extras ran
    return search.refit_singles(list(NAMES), extra=[lambda: "ref", lambda: "base"], reference=reference,
                                shares=SHARES)


def test_a_candidate_that_closes_the_gap_alone_leaves_the_far_weaker_ones_out():
    s = _Canned({"current": 1.01, "heading_bias": 3.0, "damping_rr": 4.0, "input_delay": 4.0})
    got, extras = _run(s, E_ref=24.8)
    assert extras == ["ref", "base"]
    assert s.decided == "current"
    assert set(got) == {"current", "heading_bias"}  # heading_bias is screened above 5 % of the current's share
    assert set(s.not_refitted) == {"damping_rr", "input_delay"}
    assert s.calls[0] == "current" and sorted(s.calls) == ["current", "heading_bias"]
    why = s.not_refitted["input_delay"]
    assert "current alone" in why and "1.01 < 1.1" in why and "0.002" in why
    # the ranking says why each was left out, never "screen negligible"
    screen = [SimpleNamespace(effect=n, predicted_fraction=SHARES[n], orthogonal_fraction=0.3, p_value=0.0)
              for n in NAMES]
    s.set_base(_score(24.8))
    singles = s.judge_singles(got)
    rows = {r.effect: r for r in rank(screen, singles, list(s.effs.values()), ("current",), 100.0, {},
                                      s.options, not_refitted=s.not_refitted)}
    assert rows["damping_rr"].verdict.startswith("not refitted: current alone brought the held-out E under")
    assert rows["heading_bias"].validation_gain > 0 and "not refitted" not in rows["heading_bias"].verdict


@pytest.mark.parametrize("E_first, E_ref, why", [
    (1.3, 24.8, "the first candidate leaves E above the gate"),
    (1.01, 1.05, "no structural gap before it (the reference is under the gate)"),
    (24.0, 24.8, "the first candidate does not pass the rule (gain under 5 %)"),
])
def test_every_candidate_is_refitted_unless_the_first_closes_a_real_gap(E_first, E_ref, why):
    s = _Canned({"current": E_first, "heading_bias": 3.0, "damping_rr": 4.0, "input_delay": 4.0})
    got, _ = _run(s, E_ref)
    assert set(got) == set(NAMES), why
    assert s.decided is None and not s.not_refitted, why


@pytest.mark.parametrize("options", [DiagnoseOptions(decided_share=0.0), DiagnoseOptions(refit_all=True)])
def test_the_user_can_ask_for_every_refit(options):
    s = _Canned({"current": 1.01, "heading_bias": 3.0, "damping_rr": 4.0, "input_delay": 4.0}, options)
    got, _ = _run(s, E_ref=24.8)
    assert set(got) == set(NAMES) and not s.not_refitted


def test_decided_share_is_checked():
    with pytest.raises(DataError, match="decided_share"):
        DiagnoseOptions(decided_share=1.5)
