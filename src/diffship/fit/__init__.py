"""Fits: one driver, :func:`fit` (``fit(model, runs, estimator) -> FitResult``), over four estimators of one
shape — :class:`OutputError`, :class:`MultipleShooting`, :class:`PredictionError`, :class:`EquationError`
(:mod:`diffship.fit.estimator`); status as :class:`RESULTS` values. Below: output error (simulation error; single or multiple shooting), the prediction-error method
(extended Kalman filter innovations) and the equation-error baseline (optionally on EKF + RTS
smoothed runs), same result type.

``python -m diffship.fit`` is the command-line front end (:mod:`diffship.fit.cli`; its arguments and
JAX-free first checks: :mod:`diffship.fit.args`). The names below load their modules on first use,
so that the command line can answer a user's mistake before JAX is imported.
"""

__all__ = ["fit", "RESULTS", "OutputError", "EquationError", "MultipleShooting", "PredictionError", "StartsReport",
           "FitResult", "OutputErrorOptions", "fit_equation_error", "fit_output_error", "fit_both",
           "fit_multiple_shooting", "ShootingOptions", "fit_prediction_error", "PredictionErrorOptions",
           "KalmanSmoother"]

# lazily loaded names (PEP 562): name -> submodule that defines it
_LAZY = {"fit": "driver", "RESULTS": "status", "OutputError": "output_error", "EquationError": "equation_error",
         "MultipleShooting": "shooting", "PredictionError": "prediction_error", "StartsReport": "result",
         "fit_both": "both", "fit_equation_error": "equation_error", "OutputErrorOptions": "output_error",
         "fit_output_error": "output_error", "PredictionErrorOptions": "prediction_error",
         "fit_prediction_error": "prediction_error", "FitResult": "result", "ShootingOptions": "shooting",
         "fit_multiple_shooting": "shooting", "KalmanSmoother": "smoother"}


def __getattr__(name: str):
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(f"{__name__}.{_LAZY[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
