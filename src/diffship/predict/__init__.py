"""Predict standard manoeuvres from a saved fit: ``python -m diffship.predict FIT.json --manoeuvre ...``.

:func:`predict` (:mod:`diffship.predict.core`) flies turning circles, zigzags and pull-outs with
the fitted model from a trimmed approach, computes the IMO metrics at model and full scale with
intervals from the fit's covariance, and checks the IMO 2002 criteria
(:mod:`diffship.predict.criteria`); :mod:`diffship.predict.report` prints and plots it.
"""

from .core import (
    Condition as Condition,
    ManoeuvrePrediction as ManoeuvrePrediction,
    ManoeuvreSpec as ManoeuvreSpec,
    Prediction as Prediction,
    parse_manoeuvre as parse_manoeuvre,
    predict as predict,
)
from .criteria import Criterion as Criterion, check_criteria as check_criteria, overshoot_limits as overshoot_limits
from .report import plot_prediction as plot_prediction, prediction_json as prediction_json
from .report import prediction_text as prediction_text, write_prediction as write_prediction

__all__ = ["predict", "parse_manoeuvre", "ManoeuvreSpec", "Condition", "ManoeuvrePrediction", "Prediction",
           "Criterion", "check_criteria", "overshoot_limits", "prediction_text", "plot_prediction",
           "prediction_json", "write_prediction"]
