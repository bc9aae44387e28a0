"""Predict standard manoeuvres from a saved fit: ``python -m diffship.predict FIT.json --manoeuvre ...``.

:func:`predict` (:mod:`diffship.predict.core`) flies turning circles, zigzags and pull-outs with
the fitted model from a trimmed approach, computes the IMO metrics at model and full scale with
intervals from the fit's covariance, and checks the IMO 2002 criteria
(:mod:`diffship.predict.criteria`); :mod:`diffship.predict.report` prints and plots it.
"""

from .core import Condition as Condition
from .core import ManoeuvrePrediction as ManoeuvrePrediction
from .core import ManoeuvreSpec as ManoeuvreSpec
from .core import Prediction as Prediction
from .core import parse_manoeuvre as parse_manoeuvre
from .core import predict as predict
from .criteria import Criterion as Criterion
from .criteria import check_criteria as check_criteria
from .criteria import overshoot_limits as overshoot_limits
from .report import plot_prediction as plot_prediction
from .report import prediction_json as prediction_json
from .report import prediction_text as prediction_text
from .report import write_prediction as write_prediction

__all__ = [
    "Condition",
    "Criterion",
    "ManoeuvrePrediction",
    "ManoeuvreSpec",
    "Prediction",
    "check_criteria",
    "overshoot_limits",
    "parse_manoeuvre",
    "plot_prediction",
    "predict",
    "prediction_json",
    "prediction_text",
    "write_prediction",
]
