"""From runs to padded arrays that one compiled simulation can batch over.

Runs may differ in length and sampling. They are stacked into arrays of shape ``(R, N, ...)``
with ``N`` the longest run rounded up to a *bucket* (:func:`bucket_length`: at most 1/8 more
samples), so that new data of a similar size reuse the compiled programs (in this process and,
through the persistent cache, in the next); shorter runs are continued with their last time step
and last input, and a mask removes the padded samples from every residual and metric.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from ..data import Run
from ..errors import DataError
from ..models import AbstractModel
from ..preprocess import Filter
from ..simulate import initial_state, model_inputs

__all__ = ["Batch", "make_batch", "default_channels", "bucket_length", "unfitted_positions"]

#: Channels left out of the default channels: absolute positions drift over long runs where the model misses and put
#: LM in local minima from poor starts. Output error fits the rest first and adds them where a Hausman test finds they
#: agree (:mod:`diffship.fit.positions`); ``--channels`` names them outright.
NOT_FITTED_BY_DEFAULT = ("x0", "y0")


@dataclasses.dataclass(frozen=True, eq=False)
class Batch:
    names: tuple[str, ...]
    channels: tuple[str, ...]
    ts: np.ndarray  # (R, N)
    us: np.ndarray  # (R, N, n_u)
    ys: np.ndarray  # (R, N, n_c)
    mask: np.ndarray  # (R, N)
    x0: np.ndarray  # (R, n_x)
    lengths: tuple[int, ...]

    @property
    def n_residuals(self) -> int:
        return int(self.mask.sum()) * len(self.channels)


def bucket_length(n: int) -> int:
    """``n`` rounded up to the next multiple of ``2^(⌊log2 n⌋ − 3)`` (≤ 12.5 % padding; ≥ n)."""
    if n <= 16:
        return n
    step = 1 << (int(n).bit_length() - 4)
    return -(-n // step) * step


def unfitted_positions(model: AbstractModel, runs: Sequence[Run], channels: Sequence[str] | None) -> list[str]:
    """A note where every run measures positions that the default channels leave out (:data:`NOT_FITTED_BY_DEFAULT`):
    multiple shooting, prediction error, and output error with ``positions="off"`` (by default output error tests them,
    :mod:`diffship.fit.positions`).

    Where the model is right they carry information the other channels do not: on the independent USV truth of
    ``benchmarks/fossen3_crlb.py`` (GNSS 0.5 m) Xu's Cramér–Rao bound is 2.9 % with them and 3.8 % without, and
    the fit reaches the bound of its channels on every seed; where it misses (the MMG on the HSVA KVLCC2 zigzags) their
    drift decides the fit, and the plain command with them fails its held-out runs."""
    left = [c for c in NOT_FITTED_BY_DEFAULT if c in model.output_names and all(r.has(c) for r in runs)]
    if channels is not None or not left:
        return []
    return [f"channels: {', '.join(left)} in every run but not fitted (where the model misses, a position's drift "
            f"decides the fit; single-shooting output error adds them where they agree: --positions test); where it "
            f"is right they narrow the intervals: --channels "
            f"{' '.join(c for c in model.output_names if all(r.has(c) for r in runs))}"]


def default_channels(model: AbstractModel, runs: Sequence[Run]) -> tuple[str, ...]:
    chans = tuple(
        c for c in model.output_names if c not in NOT_FITTED_BY_DEFAULT and all(r.has(c) for r in runs)
    )
    if not chans:
        raise DataError(
            f"model {model.name} predicts {', '.join(model.output_names)}, but none of these channels is in every run "
            f"({', '.join(r.name for r in runs)}); map your columns with --columns, e.g. --columns psi=heading"
        )
    return chans


def make_batch(
    model: AbstractModel,
    runs: Sequence[Run],
    channels: Sequence[str] | None = None,
    flt: Filter = Filter(),
    x0: Sequence[np.ndarray] | None = None,
    *,
    bucket: bool = True,
) -> Batch:
    if not runs:
        raise DataError("no runs given")
    channels = tuple(channels) if channels else default_channels(model, runs)
    unknown = [c for c in channels if c not in model.output_names]
    if unknown:
        raise DataError(
            f"channel(s) {', '.join(unknown)} are not outputs of model {model.name} "
            f"(it predicts {', '.join(model.output_names)})"
        )
    for r in runs:
        r.require(channels, f"fitting channels {', '.join(channels)}")
    n = bucket_length(max(r.n for r in runs)) if bucket else max(r.n for r in runs)
    R = len(runs)
    ts = np.zeros((R, n))
    us = np.zeros((R, n, len(model.input_names)))
    ys = np.zeros((R, n, len(channels)))
    mask = np.zeros((R, n), dtype=bool)
    for i, r in enumerate(runs):
        k = r.n
        t = np.asarray(r.time, dtype=np.float64)
        last_dt = t[-1] - t[-2]
        ts[i, :k] = t
        ts[i, k:] = t[-1] + last_dt * np.arange(1, n - k + 1)
        u = model_inputs(model, r)
        us[i, :k] = u
        us[i, k:] = u[-1]
        for j, c in enumerate(channels):
            y = np.asarray(r[c], dtype=np.float64)
            ys[i, :k, j] = np.unwrap(y) if c in model.angle_outputs else y
        mask[i, :k] = True
    x0s = np.stack([np.asarray(v, dtype=np.float64) for v in x0]) if x0 is not None else np.stack(
        [initial_state(model, r, flt) for r in runs]
    )
    return Batch(tuple(r.name for r in runs), channels, ts, us, ys, mask, x0s, tuple(r.n for r in runs))
