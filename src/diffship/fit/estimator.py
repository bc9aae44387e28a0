r"""What an estimator is: how it assembles residuals and which schedule of solves it runs.

Every estimator of diffship — :class:`~diffship.fit.OutputError`,
:class:`~diffship.fit.MultipleShooting`, :class:`~diffship.fit.PredictionError`,
:class:`~diffship.fit.EquationError` — is a frozen settings object with the four methods of
:class:`AbstractEstimator`. The one driver, :func:`diffship.fit.fit`, calls them in this order and
does everything else once (validation, priors, candidate and spread starts, multi-start, the
covariance, relabelling to the canonical parametrisation, identifiability, status and the
:class:`~diffship.fit.FitResult`):

1. :meth:`~AbstractEstimator.prepare` → a :class:`Problem` (compiled programs and their data);
2. :meth:`~AbstractEstimator.start_cost` for every candidate start (``inf``: it blows up);
3. :meth:`~AbstractEstimator.first_solves` from the finite starts together (multi-start);
4. :meth:`~AbstractEstimator.finish` from the best of them → a :class:`Solved`: the point, its
   residuals and the Jacobian the covariance is formed from.

This follows optimistix (``least_squares(fn, solver, y0) -> Solution``: one loop, solvers as
settings objects with ``init``/``step``/``terminate``) and lineax (``init`` prepares once,
``compute`` runs per call). Adding an estimator adds one class and one line in the shared test
battery (``tests/fit/test_battery.py``), never a second driver.

**The unknowns** of every estimator are one flat vector ``z = (z_θ, nuisance)``: the free
parameters in the scaled unconstrained space of a :class:`~diffship.params.ParamSpec`, then the
estimator's own nuisance unknowns (initial-state offsets, segment states, noise levels).
"""

from __future__ import annotations

import abc
import dataclasses
from collections.abc import Callable, Sequence
from typing import Any, ClassVar

import numpy as np

from ..data import Run
from ..models import AbstractModel
from ..params import ParamSpec
from .priors import Priors

__all__ = ["AbstractEstimator", "OnOutputError", "Problem", "Solved"]


@dataclasses.dataclass(frozen=True, eq=False)
class Problem:
    """A prepared estimation problem (what :meth:`AbstractEstimator.prepare` returns).

    Attributes:
        model: the model at the spec's values (the fixed values and the first start).
        spec: free/fixed split, bounds and scales.
        runs: the training runs.
        channels: fitted channels (equation names for equation error).
        n_nuisance: number of unknowns after the free parameters.
        nuisance_names: their names (for the identifiability messages).
        priors: the priors of the fit (may be empty).
        compile_seconds: compilation time spent preparing.
        state: the estimator's own objects (kernel, data, compiled functions, ...).
    """

    model: AbstractModel
    spec: ParamSpec
    runs: tuple[Run, ...]
    channels: tuple[str, ...]
    n_nuisance: int
    nuisance_names: tuple[str, ...]
    priors: Priors
    compile_seconds: float
    state: dict[str, Any]

    @property
    def n_params(self) -> int:
        return len(self.spec.free_names)

    def z_start(self, values) -> np.ndarray:
        """The unknowns at parameter ``values`` with the nuisance unknowns at their starts."""
        return np.concatenate([self.spec.to_z(values), np.asarray(self.state.get("nuisance0", np.zeros(self.n_nuisance)),
                                                                  dtype=np.float64)])


@dataclasses.dataclass(frozen=True, eq=False)
class Solved:
    """An estimator's optimum, with what the covariance is formed from.

    Attributes:
        z: the unknowns at the optimum.
        r_data: the data residuals there (normalised; the layout ``mask`` describes).
        J_data: their Jacobian with respect to the unknowns in ``θ/scale`` units (not ``z``: a
            parameter near a log-mapped bound must not hide its direction).
        J_extra: further unit-variance rows (priors, continuity defects), ``(k, n_z)``; ``r_extra`` their values.
        variance: σ̂² of the data rows, or ``None`` to estimate it from ``r_data``.
        dof: degrees of freedom of that estimate.
        kind: covariance kind for the data rows (``"auto"``: HAC where the residuals are coloured).
        mask, n_channels: the data rows' run layout (``None``: no whiteness test).
        input_meat, input_noise: measured-input noise propagated (errors in variables), or ``None``.
        result: the estimator's outcome (:class:`~diffship.fit.status.RESULTS`).
        steps: solver steps in total (the first solve included).
        seconds: wall time of the solves (compiled programs warm).
        compile_seconds: compilation time spent after :meth:`AbstractEstimator.prepare`.
        cost: ``½‖r_data‖²``; ``prior_cost``: the prior rows' part.
        channel_scales, noise_std: per channel (model units).
        initial_states: per-run initial states used.
        run_names: the runs' names.
        messages: notes for people.
        info: method-specific facts for the JSON.
        start_values: the free parameters at the start of :meth:`~AbstractEstimator.finish` (model units).
    """

    z: np.ndarray
    r_data: np.ndarray
    J_data: np.ndarray
    J_extra: np.ndarray
    r_extra: np.ndarray
    result: Any
    steps: int
    seconds: float
    compile_seconds: float
    cost: float
    channel_scales: dict[str, float]
    noise_std: dict[str, float]
    initial_states: tuple
    run_names: tuple[str, ...]
    variance: float | None = None
    dof: int | None = None
    kind: str = "white"
    mask: np.ndarray | None = None
    n_channels: int = 1
    input_meat: np.ndarray | None = None
    input_noise: dict[str, float] | None = None
    prior_cost: float = 0.0
    messages: tuple[str, ...] = ()
    info: dict[str, Any] = dataclasses.field(default_factory=dict)


class AbstractEstimator(abc.ABC):
    """An estimator: settings (dataclass fields) plus how residuals are assembled and solved.

    Subclasses are frozen dataclasses. Class attributes:

    * ``method``: the name in results and reports (``"output_error"``, ...).
    * ``uses_priors``: whether the model's reference priors apply by default.
    """

    method: ClassVar[str]

    # settings every estimator has (fields of the dataclass subclasses)
    priors: Priors | None
    reference_priors: bool
    prior_rel_sd: float

    @abc.abstractmethod
    def prepare(self, model: AbstractModel, runs: Sequence[Run], spec: ParamSpec, channels: Sequence[str] | None,
                priors: Priors, say: Callable[[str], None]) -> Problem:
        """Everything computed once: data arrays, scales, compiled programs."""

    @abc.abstractmethod
    def start_cost(self, problem: Problem, z: np.ndarray) -> float:
        """``½‖r‖²`` at ``z`` (``inf`` where the simulation or filter blows up)."""

    @abc.abstractmethod
    def first_solves(self, problem: Problem, zs: Sequence[np.ndarray],
                     say: Callable[[str], None]) -> list[tuple[np.ndarray, float, int]]:
        """The first solve from each start, together: ``[(z, cost, steps), ...]`` with costs on one
        scale for all starts (``inf`` where it blew up)."""

    @abc.abstractmethod
    def finish(self, problem: Problem, z: np.ndarray, steps: int, say: Callable[[str], None]) -> Solved:
        """The rest of the schedule from the best first solve (``steps`` it took), and the linearisation."""

    @abc.abstractmethod
    def residuals(self, problem: Problem, z: np.ndarray) -> np.ndarray:
        """The data rows of the residual at ``z`` with the weights :meth:`finish` ended with (after it
        ran; the rows ``Solved.J_data`` linearises, up to the padding layout)."""

    def describe(self) -> str:
        """One line naming the estimator and its main settings."""
        return self.method.replace("_", " ")


class OnOutputError(AbstractEstimator):
    """An estimator built on output error's settings (field ``oe``): priors and the start rule are its."""

    oe: Any

    @property
    def priors(self):
        return self.oe.priors

    @property
    def reference_priors(self):
        return self.oe.reference_priors

    @property
    def prior_rel_sd(self):
        return self.oe.prior_rel_sd

    @property
    def choose(self):
        return self.oe.choose
