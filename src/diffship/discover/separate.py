r"""Equivalent explanations: structures the criterion cannot tell apart, and the manoeuvre that would.

Two structures whose information criteria differ by less than the selection margin
(:data:`~diffship.discover.discovery.MARGIN`, a BIC difference of 2: "not worth more than a bare mention",
Kass & Raftery, JASA 90, 1995) explain the training runs equally well. Picking one silently hides that the
data do not decide. :func:`separating_manoeuvre` says which experiment would: every fitted structure is
simulated through each **probe manoeuvre** — each logged run's inputs as logged and scaled by
:data:`GAINS` (the same manoeuvre driven harder, where terms of higher order differ most) — from the run's
first measured state, and the probe whose predicted outputs differ most between the structures is named.

The difference of two predictions :math:`\hat y^A, \hat y^B` on a probe is

.. math:: d = \Big(\frac{1}{n_c}\sum_c \frac{\mathrm{mean}_t\,(\hat y^A_c - \hat y^B_c)^2}{\sigma_c^2}\Big)^{1/2},

with :math:`\sigma_c` each channel's sensor noise, estimated from the logged runs
(:func:`diffship.initial.channel_noise`; not a fit's residual level, which carries the model error):
:math:`d = 1` is a difference the size of the sensor noise, which one run of that manoeuvre can barely resolve;
the report gives the heading part in degrees. Angles are wrapped before squaring. Every structure starts each
probe from the same state, the run's filtered first sample (:func:`diffship.simulate.initial_state`), so that
the difference is the structures' alone. A probe on which either structure's simulation blows up is
skipped (that too would separate them, but not as a measurement a user should be sent to make).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence

import numpy as np

from ..data import Run
from ..fit import FitResult
from ..fit.problem import make_batch
from ..initial import channel_noise
from ..metrics import evaluate
from ..simulate import initial_state

__all__ = ["GAINS", "Separation", "probe_runs", "separating_manoeuvre"]

#: Input gains of the probe manoeuvres: each logged run as logged, and driven harder.
GAINS = (1.0, 1.5)


@dataclasses.dataclass(frozen=True)
class Separation:
    """The probe manoeuvre whose predictions differ most between two fitted structures.

    Attributes:
        manoeuvre: its label (``"<run> as logged"`` or ``"<run> with its inputs ×1.5"``).
        difference: :math:`d` of the module docstring (1 = the sensor noise).
        heading_deg: RMS difference of the predicted heading [°] (nan without a heading output).
        per_probe: ``{label: d}`` of every probe simulated.
    """

    manoeuvre: str
    difference: float
    heading_deg: float
    per_probe: dict[str, float]

    def text(self) -> str:
        head = f"heading {self.heading_deg:.2f}° RMS apart, " if math.isfinite(self.heading_deg) else ""
        return f"{self.manoeuvre} ({head}{self.difference:.1f}× the sensor noise)"

    def to_dict(self) -> dict:
        return {"manoeuvre": self.manoeuvre, "difference_over_noise": self.difference,
                "heading_rms_deg": self.heading_deg, "per_probe": dict(self.per_probe)}


def probe_runs(runs: Sequence[Run], input_names: Sequence[str],
               gains: Sequence[float] = GAINS) -> list[tuple[str, Run]]:
    """``(label, run)`` of every probe: each run with its ``input_names`` channels scaled by each gain (a new Run;
    the measured outputs are kept only for the start state)."""
    out = []
    for r in runs:
        for g in gains:
            if g == 1.0:
                out.append((f"{r.name} as logged", r))
                continue
            ch = {c: (np.asarray(r[c], dtype=float) * g if c in input_names else np.asarray(r[c], dtype=float))
                  for c in r.channels}
            out.append((f"{r.name} with its inputs ×{g:g}", Run(f"{r.name}_x{g:g}", np.asarray(r.time), ch,
                                                               dict(r.metadata))))
    return out


def separating_manoeuvre(fits: Sequence[FitResult], runs: Sequence[Run], noise: Mapping[str, float] | None = None,
                         gains: Sequence[float] = GAINS) -> Separation | None:
    """The probe (module docstring) on which the predictions of ``fits`` differ most (the largest pairwise
    :math:`d`), or ``None`` when no probe simulates with every fit. ``noise``: each channel's sensor noise (default:
    estimated from ``runs``)."""
    if len(fits) < 2 or not runs:
        return None
    model0 = fits[0].model
    if noise is None:
        b = make_batch(model0, runs, [c for c in fits[0].channels if all(r.has(c) for r in runs)])
        noise = dict(zip(b.channels, map(float, channel_noise(b.ys, b.mask))))
    probes = probe_runs(runs, model0.input_names, gains)
    chans = [c for c in fits[0].channels if c in noise and noise[c] > 0]
    x0 = [initial_state(model0, r) for _, r in probes]  # one start per probe, the same for every structure
    sims = [evaluate(f.model, [r for _, r in probes], x0, channels=chans, integrator=f.integrator) for f in fits]
    angles = set(model0.angle_outputs)
    per, head = {}, {}
    for label, r in probes:
        ok = [ev.simulated[r.name] for ev in sims if ev.per_run[r.name]["ok"]]
        if len(ok) < len(sims):
            continue
        for i in range(len(ok)):
            for j in range(i + 1, len(ok)):
                ms = {}  # mean square difference of each channel
                for c in chans:
                    dc = np.asarray(ok[i][c], dtype=float) - np.asarray(ok[j][c], dtype=float)
                    ms[c] = float(np.mean(np.angle(np.exp(1j * dc)) ** 2 if c in angles else dc * dc))
                d = math.sqrt(float(np.mean([ms[c] / noise[c] ** 2 for c in chans])))
                if math.isfinite(d) and d > per.get(label, -1.0):
                    per[label] = d
                    head[label] = math.degrees(math.sqrt(ms["psi"])) if "psi" in ms else math.nan
    if not per:
        return None
    top = max(per, key=per.get)
    return Separation(top, per[top], head[top], per)
