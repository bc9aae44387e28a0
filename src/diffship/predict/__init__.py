"""Predict standard manoeuvres from a saved fit: ``python -m diffship.predict FIT.json --manoeuvre ...``.

:func:`predict` (:mod:`diffship.predict.core`) flies turning circles, zigzags and pull-outs with
the fitted model from a trimmed approach, computes the IMO metrics at model and full scale with
intervals from the fit's covariance, and checks the IMO 2002 criteria
(:mod:`diffship.predict.criteria`); :mod:`diffship.predict.report` prints and plots it.
:mod:`diffship.predict.sampling` flies the parameter draws of the intervals vmapped;
:mod:`diffship.predict.cross` judges a fit on measured runs of manoeuvre types it was not
trained on (cross-manoeuvre validation; report, JSON and figure in
:mod:`diffship.predict.cross_report`).
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
from .cross import CrossValidation as CrossValidation
from .cross import RunType as RunType
from .cross import classify_run as classify_run
from .cross import cross_validate as cross_validate
from .cross_report import cross_json as cross_json
from .cross_report import cross_text as cross_text
from .cross_report import plot_cross as plot_cross
from .report import plot_prediction as plot_prediction
from .report import prediction_json as prediction_json
from .report import prediction_text as prediction_text
from .report import write_prediction as write_prediction

__all__ = [
    "Condition",
    "Criterion",
    "CrossValidation",
    "ManoeuvrePrediction",
    "ManoeuvreSpec",
    "Prediction",
    "RunType",
    "check_criteria",
    "classify_run",
    "cross_json",
    "cross_text",
    "cross_validate",
    "overshoot_limits",
    "parse_manoeuvre",
    "plot_cross",
    "plot_prediction",
    "predict",
    "prediction_json",
    "prediction_text",
    "write_prediction",
]
