"""Options of :func:`~.diagnosis.diagnose`: what to screen, how much to refit, the acceptance rule."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence

from ..errors import DataError
from ..models.effects import EFFECT_NAMES

__all__ = ["DiagnoseOptions"]


@dataclasses.dataclass(frozen=True)
class DiagnoseOptions:
    """What :func:`~.diagnosis.diagnose` screens and how it decides (defaults: the documented rule).

    Candidates:
        effects: ``"all"`` or names from :data:`~.effects.EFFECT_NAMES`.
        channels: channels of the base fit (default: what the model predicts and the runs have,
            positions included — :func:`~.diagnosis.diagnosis_channels`).
        noise: per-channel noise floor (known sensor noise); estimated from the data if None.
        position_accuracy: accuracy of the positioning system [m] (None: unknown); the position
            floor is at least this (:func:`~.floors.physical_position_floor`).
        position_drift: drift per distance sailed [-] the position floor allows (default
            0.1 %: a track off by 0.1 % of the distance sailed is at the floor).

    Effort:
        max_refits: candidates refitted by screening rank, plus up to ``max_absorbed`` of those
            the base parameters absorb (o_k < 0.1), which the screen under-rates.
        refit_all: refit every candidate instead (``decided_share`` then does not apply).
        decided_share: when the first candidate by screening rank, refitted before the others,
            passes the rule and alone brings the held-out E under the gap gate, the candidates
            whose screened share f_k is below this fraction of its share are not refitted (under
            the gate no effect can lower E by more than the noise band; :meth:`~.which.Search.refit_singles`).
            0: refit them all.
        greedy_steps: effects on the greedy path at most (after the first, each must pass the
            rule against the previous step; the path stops earlier under the gap gate). On real
            model-basin logs the base model's own structural gap (two damping couplings on the
            HSVA KVLCC2 zigzags) can take the first two steps: an injected 0.5-s logging-clock
            offset between rudder and motion passed the rule only at a third, while the logs
            without it stopped at two (``benchmarks/results/withheld_real_mmg.md``). The default
            stays 2: the third step's joint refits took the KVLCC2 diagnosis from 123 s to 190 s
            (empty compile cache, 2 cores) without changing its verdict.
        max_pairs: when no single effect passes, refit up to this many pairs of the best single
            candidates jointly (two effects that compensate each other alone).
        max_iter: Levenberg–Marquardt iterations per refit; fit_steps: of the base fit.
        stall: ``(W, ρ)``: the base fit and every refit stop early when their cost falls by less
            than ρ·cost over W Levenberg–Marquardt steps (a mis-specified model crawls for
            hundreds of steps that move its cost by a fraction of a percent; its verdict does not
            hang on them). The base fit then reports "stopped early: the cost stalled" (not
            converged) and candidates are judged against the no-effect refit, stopped by the same
            rule. ``None``: off (the step caps alone).

    Held-out start (:mod:`.start`):
        start_bound: every compared model starts each held-out run at its initial state estimated within its
            sensor noise (:mod:`diffship.initial`: a prior row on each logged state, centred on its first sample);
            a finite bound also keeps the logged states within that many noise floors of the log (default
            ``inf``: the prior alone, the rule of every fit and metric).

    Acceptance rule (see :mod:`.which`):
        gap_gate: a structural gap exists when E ≥ gap_gate (E = 1 at the noise floor). None
            (default): from the data — the scatter of E under no structural error given the
            validation and noise-floor sample counts, :func:`~.where.structural_gate` (z =
            ``gate_z``); a number fixes it (the former rule was a fixed 1.1, which ignored how
            many samples measured E). The drop of E an effect must give (``min_gain`` aside) is
            the same noise band, gate − 1 (or 2 SE of the per-run gains, when larger).
        gate_z: standard deviations of the null scatter of E² the gate sits above.
        min_gain: smallest relative validation gain.
        possible_min_dE: under the gate, the smallest drop of E for a *possible* effect (low
            confidence, not attributed; :mod:`.which`): twice the ±0.01 scatter of E on
            no-effect data.
        min_shrink: smallest fraction of the structural gap removed.
        confusable_margin: candidates that pass and come within this relative margin of the
            winner's validation error are reported as confusable.
        tie_share: a passing candidate whose validation error is within this share of the
            winner's gain is a rival: refitted jointly with the winner to decide, else a tie.

    Sea state (:mod:`.sea_state`):
        sea_state: ``"auto"`` (default): check for a stochastic narrow-band disturbance when the training residuals
            have a periodic line the steering does not drive, or, with the loop closed, one it shares (an autopilot
            answering the waves); ``"always"``; ``"never"``.

    Data (:mod:`.consistency`):
        correct_data: take the data checks' findings (a heading bias, a rudder timing) out of
            the logs before the base fit; they are reported either way. A finding also needs the
            held-out misfit to fall by ``min_gain``.
    """

    effects: Sequence[str] | str = "all"
    channels: Sequence[str] | None = None
    noise: Mapping[str, float] | None = None
    position_accuracy: float | None = None
    position_drift: float = 1e-3
    max_refits: int = 4
    max_absorbed: int = 3
    refit_all: bool = False
    decided_share: float = 0.05
    greedy_steps: int = 2
    max_pairs: int = 3
    max_iter: int = 30
    fit_steps: int = 200
    stall: tuple[int, float] | None = (10, 1e-3)
    start_bound: float = math.inf
    gap_gate: float | None = None
    gate_z: float = 3.0
    min_gain: float = 0.05
    possible_min_dE: float = 0.02
    min_shrink: float = 0.3
    confusable_margin: float = 0.05
    tie_share: float = 0.1
    correct_data: bool = False
    sea_state: str = "auto"

    def __post_init__(self):
        if self.effects != "all":
            if isinstance(self.effects, str):
                raise DataError(f"effects: 'all' or a sequence of names, got {self.effects!r}")
            object.__setattr__(self, "effects", tuple(self.effects))
            bad = [n for n in self.effects if n not in EFFECT_NAMES]
            if bad:
                raise DataError(f"unknown effect(s) {', '.join(map(repr, bad))}; "
                                f"choose from: {', '.join(EFFECT_NAMES)}")
        if not (int(self.greedy_steps) == self.greedy_steps and self.greedy_steps >= 1):
            raise DataError(f"greedy_steps: a whole number of effects >= 1, got {self.greedy_steps!r}")
        if not 0 <= self.decided_share < 1:
            raise DataError(f"decided_share: a fraction in [0, 1) of the first candidate's screened share, "
                            f"got {self.decided_share!r}")
        if not self.start_bound > 0:
            raise DataError(f"start_bound: a positive number of noise floors (or inf), got {self.start_bound!r}")
        if self.sea_state not in ("auto", "always", "never"):
            raise DataError(f"sea_state: 'auto', 'always' or 'never', got {self.sea_state!r}")
        if self.channels is not None:
            object.__setattr__(self, "channels", tuple(self.channels))
        if self.stall is not None:
            w, rho = self.stall
            if not (int(w) == w and w >= 2 and 0 < rho < 1):
                raise DataError(f"stall: (steps >= 2, relative cost decrease in (0, 1)) or None, got {self.stall!r}")
            object.__setattr__(self, "stall", (int(w), float(rho)))

    @property
    def stall_lm(self) -> dict:
        """The stall rule as the Levenberg–Marquardt keywords (:meth:`diffship.fit.kernel.Kernel.solve`)."""
        return {} if self.stall is None else {"stall_steps": self.stall[0], "stall_rtol": self.stall[1]}

    @property
    def effect_names(self) -> tuple[str, ...]:
        return EFFECT_NAMES if self.effects == "all" else tuple(self.effects)
