"""Fits: output error (simulation error; single or multiple shooting), the prediction-error method
(extended Kalman filter innovations) and the equation-error baseline (optionally on EKF + RTS
smoothed runs), same result type.

``python -m diffship.fit`` is the command-line front end (:mod:`diffship.fit.cli`).
"""

from .both import fit_both as fit_both
from .equation_error import fit_equation_error as fit_equation_error
from .output_error import OutputErrorOptions as OutputErrorOptions, fit_output_error as fit_output_error
from .prediction_error import PredictionErrorOptions as PredictionErrorOptions
from .prediction_error import fit_prediction_error as fit_prediction_error
from .result import FitResult as FitResult
from .shooting import ShootingOptions as ShootingOptions
from .shooting import fit_multiple_shooting as fit_multiple_shooting
from .smoother import KalmanSmoother as KalmanSmoother

__all__ = ["FitResult", "OutputErrorOptions", "fit_equation_error", "fit_output_error", "fit_both",
           "fit_multiple_shooting", "ShootingOptions", "fit_prediction_error", "PredictionErrorOptions",
           "KalmanSmoother"]
