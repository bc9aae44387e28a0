"""Both methods on the same data: equation error first, output error started from it."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping, Sequence

from ..data import Run
from ..errors import DiffshipError
from ..models import AbstractModel
from ..params import ParamSpec
from ..preprocess import Filter
from .equation_error import fit_equation_error
from .output_error import OutputErrorOptions, fit_output_error
from .result import FitResult
from .starts import checked_start

__all__ = ["fit_both"]


def fit_both(
    model: AbstractModel,
    runs: Sequence[Run],
    *,
    spec: ParamSpec | None = None,
    methods: Sequence[str] = ("equation_error", "output_error"),
    init: Mapping[str, float] | None = None,
    flt: Filter = Filter(),
    estimate_x0: Sequence[str] | str | None = None,
    channels: Sequence[str] | None = None,
    options: OutputErrorOptions = OutputErrorOptions(),
    progress: Callable[[str], None] | None = None,
    ee_filter=None,
    n_starts: int | None = None,
) -> dict[str, FitResult]:
    """Run the requested methods on the same data; equation error's estimate is one of output error's starts.

    Output error runs through the one driver (:func:`diffship.fit.fit`): its starts are the user's
    ``init`` values (or the model's values), the equation-error estimate, the reference values and
    spread starts up to ``n_starts``, tried together; the lowest cost wins, and the result says how
    many starts reached it and whether the user's own start ended higher. ``init`` names free parameters
    only: a fixed one raises :class:`~diffship.errors.ModelError` before either method runs (as in
    :func:`~diffship.fit.fit`: its start value would silently become the value it is held at).
    ``flt`` is the equation-error differentiation filter (and the filter for initial states);
    ``ee_filter`` (e.g. a :class:`~diffship.fit.smoother.KalmanSmoother`) replaces it for equation error only;
    ``estimate_x0=None`` (default) keeps ``options.estimate_x0`` (``"auto"``: the one initial-state rule,
    :mod:`diffship.initial` — every run's initial state estimated within its sensor noise); ``"fitted"`` is
    the same rule; ``()`` or ``"data"`` takes every run's initial state from the data as exact (a noisy first
    sample then biases the estimates); ``options`` holds the other output-error settings.
    """
    say = progress or (lambda s: None)
    spec = spec or model.spec()
    init = checked_start(spec, init, "init") if init else None  # equation error starts there too
    out: dict[str, FitResult] = {}
    starts: dict[str, dict[str, float]] = {}
    if "equation_error" in methods:
        try:
            say("equation error: differentiating and solving the least-squares problem...")
            ee = fit_equation_error(model, runs, spec=spec.with_values(init) if init else spec,
                                    flt=flt if ee_filter is None else ee_filter)
            out["equation_error"] = ee
            say(f"equation error: solved in {ee.fit_seconds + ee.compile_seconds:.2f} s ({ee.status}); its verdict "
                "comes with the metrics")
            starts["the equation-error estimate"] = {n: ee.params[n] for n in ee.free}
        except DiffshipError as exc:  # baseline unavailable (e.g. missing u, v): say so, go on
            say(f"equation error not available: {exc}")
            if list(methods) == ["equation_error"]:
                raise
    if "output_error" in methods:
        if estimate_x0 is None:
            est = options.estimate_x0
        elif estimate_x0 in ("fitted", "auto", "estimate"):
            est = "auto"
        elif estimate_x0 == "data":
            est = ()
        else:
            est = tuple(estimate_x0)
        # equation error ran above: its estimate is a named start already (or it failed: no second try)
        opts = dataclasses.replace(options, estimate_x0=est, flt=flt,
                                   ee_start=options.ee_start and "equation_error" not in methods)
        out["output_error"] = fit_output_error(model, runs, spec=spec, init=init, starts=starts, channels=channels,
                                               options=opts, progress=progress, n_starts=n_starts)
    return out
