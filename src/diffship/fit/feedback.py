r"""Closed-loop evidence: does the input react to the model's past errors?

Under an autopilot (or a helmsman) the rudder is computed from the measured heading, so it reacts to whatever
moved the heading — waves and gusts included. The input is then correlated with the disturbance, and output
error with the measured rudder as input is biased (Ljung 1999, §13.4); a prediction-error fit with the right
disturbance model is not (:mod:`diffship.fit.disturbance`).

The test is a Granger (1969) regression of each input on its own past and on the past residuals of each fitted
channel (the simulation errors :math:`e = y - \hat y`), pooled over runs with an intercept per run:

.. math::
    u_k = a_i + \sum_{l=1}^{L} \alpha_l u_{k-l} + \sum_{l=1}^{L} \beta_l e_{k-l} + \varepsilon_k,
    \qquad H_0:\ \beta = 0 .

In open loop the input's future does not depend on the disturbance, so the past residuals add nothing to what
its own past predicts, however wrong the model (a model error makes :math:`e` a function of *past* inputs,
which the input's own lags already carry). Under feedback they do. ``F`` is the usual nested-model statistic
with :math:`(L, N - 2L - R)` degrees of freedom; the effect size is the partial :math:`R^2`, the share of the
input's unexplained variance that the past residuals explain. The loop is called **closed** when
:math:`p < 10^{-3}` and the partial :math:`R^2 \ge 0.02` (with thousands of samples a negligible reaction is
significant; 2 % is a reaction a fit's bias can come from). A zigzag is a relay on the heading: the rudder
reverses when the heading passes the switch angle, and the test may see it where the sea is not calm.

References:
    C. W. J. Granger, "Investigating causal relations by econometric models and cross-spectral methods",
    Econometrica 37 (1969).
    L. Ljung, *System Identification: Theory for the User*, 2nd ed., Prentice Hall 1999, §13.4 and §16.6.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence

import numpy as np
from scipy.special import fdtrc

__all__ = ["FeedbackTest", "feedback_test", "loop_evidence", "P_MAX", "SHARE_MIN"]

#: The loop is closed below this p-value ...
P_MAX = 1e-3
#: ... and when the past residuals explain at least this share of the input's unexplained variance.
SHARE_MIN = 0.02


@dataclasses.dataclass(frozen=True)
class FeedbackTest:
    """The test of one input against one channel's residuals (module docstring)."""

    input: str
    channel: str
    lags: int
    lag_seconds: float
    F: float
    p_value: float
    partial_r2: float
    n: int

    @property
    def closed(self) -> bool:
        return self.p_value < P_MAX and self.partial_r2 >= SHARE_MIN

    def line(self) -> str:
        verdict = "reacts to" if self.closed else "does not react to"
        return (f"{self.input} {verdict} past {self.channel} residuals (Granger F {self.F:.3g}, p {self.p_value:.2g}, "
                f"partial R² {100 * self.partial_r2:.1f} % over {self.lag_seconds:.3g} s)")

    def as_json(self) -> dict:
        return {**dataclasses.asdict(self), "closed": self.closed}


def _lagged(x: np.ndarray, L: int) -> np.ndarray:
    """Rows k = L … n−1 of ``[x_{k-1}, …, x_{k-L}]``."""
    return np.stack([x[L - l:len(x) - l] for l in range(1, L + 1)], axis=1)


def feedback_test(inputs: Mapping[str, Sequence[np.ndarray]], residuals: Mapping[str, Sequence[np.ndarray]],
                  dt: float, lag_seconds: float = 5.0, max_lags: int = 20) -> list[FeedbackTest]:
    """Granger tests of every input (``inputs[name]``: one array per run) against every channel's residuals
    (``residuals[channel]``: one array per run, the same runs and samples), ``L = min(max_lags, lag_seconds/dt)``
    lags (at least 1); runs shorter than ``3L + 10`` samples are left out. Returns one :class:`FeedbackTest` per
    pair with data (an input that never moves gives none)."""
    L = int(max(1, min(max_lags, round(lag_seconds / dt))))
    out = []
    for name, us in inputs.items():
        for ch, es in residuals.items():
            Xr, Xf, Y = [], [], []
            keep = [(np.asarray(u, float), np.asarray(e, float)) for u, e in zip(us, es)
                    if len(u) == len(e) and len(u) >= 3 * L + 10 and np.all(np.isfinite(u)) and np.all(np.isfinite(e))]
            R = len(keep)
            for i, (u, e) in enumerate(keep):
                ones = np.zeros((len(u) - L, R))
                ones[:, i] = 1.0
                own = np.hstack([ones, _lagged(u, L)])
                Xr.append(own)
                Xf.append(np.hstack([own, _lagged(e / (np.std(e) or 1.0), L)]))
                Y.append(u[L:])
            if not R:
                continue
            Xr, Xf, Y = np.vstack(Xr), np.vstack(Xf), np.concatenate(Y)
            if np.std(Y) == 0.0:
                continue
            rss = [float(np.sum((Y - X @ np.linalg.lstsq(X, Y, rcond=None)[0]) ** 2)) for X in (Xr, Xf)]
            dof = len(Y) - Xf.shape[1]
            if dof <= 0 or rss[0] <= 0.0:
                continue
            F = ((rss[0] - rss[1]) / L) / (rss[1] / dof) if rss[1] > 0 else np.inf
            out.append(FeedbackTest(name, ch, L, L * dt, float(F), float(fdtrc(L, dof, max(F, 0.0))),
                                    float(max(0.0, (rss[0] - rss[1]) / rss[0])), int(len(Y))))
    return out


def loop_evidence(model, runs: Sequence, ev, channels: Sequence[str], method: str = "output_error") -> dict | None:
    """The tests of every logged, moving input of ``model`` against the whole-run simulation errors of ``channels``
    (``ev``: the model's :class:`~diffship.metrics.Evaluation` on ``runs``), as the fit and diagnosis reports give
    them: ``{"closed", "tests", "text"}``; ``None`` without a usable pair."""
    runs = [r for r in runs if r.name in ev.simulated and r.n >= 20]
    if not runs:
        return None
    err = ev.errors(runs, channels, model.angle_outputs)
    res = {c: [err[r.name][c] for r in runs] for c in err[runs[0].name]}
    ins = {u: [np.asarray(r[u], float) for r in runs] for u in model.input_names if all(r.has(u) for r in runs)}
    dt = float(np.median(np.concatenate([np.diff(np.asarray(r.time, float)) for r in runs])))
    tests = feedback_test(ins, res, dt)
    if not tests:
        return None
    closed = [t for t in tests if t.closed]
    if closed:
        text = ("closed loop: " + "; ".join(t.line() for t in closed) + ". The input follows the motion (computed "
                "from it by an autopilot, a helmsman or a zigzag's switching rule, or driven by it, as a propeller's "
                "speed under load): ")
        text += ("prediction error stays consistent under feedback only with the right disturbance model (compare "
                 "--disturbance wave and ou)" if method == "prediction_error" else
                 "where the errors carry a disturbance (waves, gusts) and not only sensor noise, output error with this "
                 "input is biased; prediction error with a disturbance model is not (--method prediction-error "
                 "--disturbance wave or ou)")
    else:
        worst = max(tests, key=lambda t: t.partial_r2)
        text = f"open loop: no input reacts to past errors (largest: {worst.line()})"
    return {"closed": bool(closed), "tests": [t.as_json() for t in tests], "text": text}
