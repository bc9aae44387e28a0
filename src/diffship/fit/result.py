"""The value every fit returns."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from ..integrators import AbstractIntegrator, Diffrax
from ..models import AbstractModel

__all__ = ["FitResult"]


@dataclasses.dataclass(frozen=True, eq=False)
class FitResult:
    """Outcome of an output-error or equation-error fit, as a value.

    Attributes:
        method: ``"output_error"`` or ``"equation_error"``.
        model: the model with the fitted parameter values.
        params: all parameter values (fitted and fixed), model SI units.
        stderr: standard errors of the free parameters (same units).
        free: names of the estimated parameters.
        converged: whether the solver met its tolerances.
        status: short readable status (``"converged"``, ``"maximum number of steps ..."``).
        iterations: solver steps (1 for linear least squares).
        cost: final ``½‖r‖²`` of the normalised residuals.
        fit_seconds: wall time of the solve, compiled function warm.
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
