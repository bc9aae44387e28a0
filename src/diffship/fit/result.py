"""The value every fit returns."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from ..integrators import AbstractIntegrator, Diffrax
from ..models import AbstractModel
from .status import RESULTS, by_name, message, name_of, usable

__all__ = ["FitResult", "StartsReport"]


@dataclasses.dataclass(frozen=True)
class StartsReport:
    """What the starts of a fit did (:mod:`diffship.fit.driver`).

    Attributes:
        labels: each start's label, in the order tried (``"the model's values"``, ``"the
            equation-error estimate"``, ``"spread start 1"``, ...).
        costs: each start's cost after the first solve (``inf`` where it blew up or was skipped).
        best: index of the start the result continued from.
        reached: how many starts ended within the tolerance of the best cost (half the residual
            variance: about one standard error in one parameter direction).
        tolerance: that tolerance, in cost units.
        user: index of the user's own start (``--init``), or ``None``.
        stopped: indices of starts stopped on the warm-up while still running, above the cost of
            a start that had converged there (dominated: not run to their end; their cost is the
            whole runs' where they stopped).
    """

    labels: tuple[str, ...]
    costs: tuple[float, ...]
    best: int
    reached: int
    tolerance: float
    user: int | None = None
    stopped: tuple[int, ...] = ()

    @property
    def user_higher(self) -> bool:
        """Whether the user's own start ended at a higher cost than the best start."""
        return self.user is not None and self.costs[self.user] > self.costs[self.best] + self.tolerance

    def describe(self) -> str:
        """One line for the report."""
        n = len(self.labels)
        text = (f"starts: {n} tried, {self.reached} of them reached the best cost {self.costs[self.best]:.6g} "
                f"(within {self.tolerance:.2g}); the result continued from {self.labels[self.best]}")
        if self.stopped:
            text += (f"; {len(self.stopped)} stopped on the warm-up, still running above a converged start's cost "
                     f"({', '.join(self.labels[i] for i in self.stopped)})")
        if self.user_higher:
            text += (f"; WARNING: your start ({self.labels[self.user]}) ended higher, at "
                     f"{self.costs[self.user]:.6g}")
        return text

    def as_json(self) -> dict:
        return {"n": len(self.labels), "labels": list(self.labels), "costs": [float(c) for c in self.costs],
                "best": self.labels[self.best], "reached_best": self.reached, "tolerance": self.tolerance,
                "user_start_higher": self.user_higher, "stopped_on_warmup": [self.labels[i] for i in self.stopped]}


@dataclasses.dataclass(frozen=True, eq=False)
class FitResult:
    """Outcome of an output-error or equation-error fit, as a value.

    Attributes:
        method: ``"output_error"`` or ``"equation_error"``.
        model: the model with the fitted parameter values.
        params: all parameter values (fitted and fixed), model SI units.
        stderr: standard errors of the free parameters (same units).
        free: names of the estimated parameters.
        converged: whether the solver met its tolerances (``result == RESULTS.successful``).
        status: readable text of ``result`` (``"converged"``, ``"not converged: ..."``).
        iterations: solver steps (1 for linear least squares).
        cost: final ``½‖r‖²`` of the normalised residuals.
        fit_seconds: wall time of the solves (every start's first solve, then the rest from the best),
            compiled programs warm (``info["solve_seconds"]`` splits it).
        compile_seconds: time spent compiling (0 when a cached compiled fit was reused).
        channels: fitted measured channels.
        channel_scales: the per-channel normalisation used for the residuals.
        noise_std: per-channel RMS of the final residuals (model units).
        initial_states: per-run initial states used (``model.state_names`` order).
        covariance: covariance of the free parameters (model units), or ``None``.
        integrator: the integrator the fit simulated with; evaluation and diagnosis of this fit
            use the same one.
        messages: notes for people (start chosen, filters used, warnings).
        info: anything method-specific (filter, weights, ...).
        result: the outcome as a :class:`~diffship.fit.status.RESULTS` value (given, or read from
            ``converged``/``status`` for results built the older way); ``converged`` and ``status``
            are made consistent with it.
        starts: what the starts did (:class:`StartsReport`), where the driver tried several.
        spec: the parameter specification the fit solved (free names, scales, bounds), where the
            driver made it: with ``estimator`` it rebuilds the same problem (the bootstrap's refits).
        estimator: the estimator settings object that made the fit (``OutputError(...)``, ...).
    """

    method: str
    model: AbstractModel
    params: dict[str, float]
    stderr: dict[str, float]
    free: tuple[str, ...]
    converged: bool
    status: str
    iterations: int
    cost: float
    fit_seconds: float
    compile_seconds: float
    channels: tuple[str, ...] = ()
    channel_scales: dict[str, float] = dataclasses.field(default_factory=dict)
    noise_std: dict[str, float] = dataclasses.field(default_factory=dict)
    initial_states: tuple[np.ndarray, ...] = ()
    run_names: tuple[str, ...] = ()
    covariance: np.ndarray | None = None
    integrator: AbstractIntegrator = Diffrax()
    messages: tuple[str, ...] = ()
    info: dict[str, Any] = dataclasses.field(default_factory=dict)
    result: RESULTS | None = None
    starts: StartsReport | None = None
    spec: Any = None
    estimator: Any = None

    def __post_init__(self):
        if self.result is None:
            result = RESULTS.successful if self.converged else by_name(self.status)
            object.__setattr__(self, "result", result)
        object.__setattr__(self, "converged", bool(self.result == RESULTS.successful))
        object.__setattr__(self, "status", message(self.result))

    @property
    def outcome(self) -> str:
        """The name of ``result`` (``"successful"``, ``"max_steps_reached"``, ``"simulation_blew_up"``, ...)."""
        return name_of(self.result)

    @property
    def usable(self) -> bool:
        """Whether the estimate may be used (converged, or stopped at a limit with finite values)."""
        return usable(self.result)

    @property
    def model_name(self) -> str:
        return self.model.name

    def correlation(self) -> np.ndarray | None:
        """Correlation matrix of the free parameters."""
        if self.covariance is None:
            return None
        d = np.sqrt(np.diag(self.covariance))
        return self.covariance / np.outer(d, d)

    def summary(self) -> str:
        """A short text table of the free parameters."""
        lines = [f"{self.method.replace('_', ' ')} fit of {self.model_name}: {self.status} "
                 f"({self.iterations} iterations, cost {self.cost:.4g}, fit {self.fit_seconds:.2f} s, "
                 f"compile {self.compile_seconds:.2f} s)"]
        for n in self.free:
            se = self.stderr.get(n, math.nan)
            rel = abs(se / self.params[n]) * 100 if self.params[n] else math.nan
            lines.append(f"  {n:>8s} = {self.params[n]: .6g} ± {se:.3g}  ({rel:.2g} %)")
        return "\n".join(lines)
