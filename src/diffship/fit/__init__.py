"""Fits: output error (simulation error) and the equation-error baseline, same result type.

``python -m diffship.fit`` is the command-line front end (:mod:`diffship.cli`).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence

from ..data import Run
from ..models._base import AbstractModel
from ..params import ParamSpec
from ..preprocess import Filter
from .equation_error import fit_equation_error as fit_equation_error
from .output_error import fit_output_error as fit_output_error
from .result import FitResult as FitResult

__all__ = ["FitResult", "fit_equation_error", "fit_output_error", "fit_both"]


def fit_both(
    model: AbstractModel,
    runs: Sequence[Run],
    *,
    spec: ParamSpec | None = None,
    methods: Sequence[str] = ("equation_error", "output_error"),
    init: Mapping[str, float] | None = None,
    flt: Filter = Filter(),
    estimate_x0: Sequence[str] | str = "fitted",
    channels: Sequence[str] | None = None,
    progress: Callable[[str], None] | None = None,
    **oe_kw,
) -> dict[str, FitResult]:
    """Run the requested methods on the same data; output error starts from equation error.

    Output error's candidate starts are, in order: the user's ``init`` values (or the model's
    reference values) and the equation-error estimate where one is available; the start with
    the lowest finite simulation cost is used. ``estimate_x0="fitted"`` estimates the initial
    values of the fitted channels' states (``()`` takes them from the data).
    """
    say = progress or (lambda s: None)
    spec = spec or model.spec()
    if init:
        spec = spec.with_values(init)
    out: dict[str, FitResult] = {}
    starts = []
    if "equation_error" in methods:
        try:
            say("equation error: differentiating and solving the least-squares problem...")
            ee = fit_equation_error(model, runs, spec=spec, flt=flt)
            out["equation_error"] = ee
            say(f"equation error: {ee.status} in {ee.fit_seconds + ee.compile_seconds:.2f} s")
            starts.append({n: ee.params[n] for n in ee.free})
        except Exception as exc:  # baseline unavailable (e.g. missing u, v): say so, go on
            from ..errors import DiffshipError

            if not isinstance(exc, DiffshipError):
                raise
            say(f"equation error not available: {exc}")
            if methods == ("equation_error",) or list(methods) == ["equation_error"]:
                raise
    if "output_error" in methods:
        if estimate_x0 == "fitted":
            from .problem import default_channels

            chans = tuple(channels) if channels else default_channels(model, runs)
            est = model.states_for_channels(chans)
        else:
            est = tuple(estimate_x0)
        out["output_error"] = fit_output_error(
            model, runs, spec=spec, starts=starts, channels=channels, estimate_x0=est, flt=flt, progress=progress,
            choose="first" if init else "best", **oe_kw,
        )
    return out
