r"""The fit file: one fit as a versioned JSON document, and loading it back.

A fit file (``"schema": "diffship.fit/1"``) holds everything needed to predict with a fit
without the data or the code that made it:

* ``model``: the model's name and its registry key (``--model NAME``); for a model with library terms
  (:mod:`diffship.models.terms`, ``python -m diffship.discover``) the key is its base model's and
  ``terms`` lists the term names, from which :func:`load_fit` rebuilds it;
* ``params`` (every parameter, SI units as in ``units``), ``free`` (estimated), ``fixed``
  (held values), ``stderr`` and ``covariance`` (free parameters, ``covariance.names`` order;
  ``null`` when the method gives none; ``Infinity`` for unidentifiable directions), ``priors``
  (``{name: {"mean", "sd", "source"}}`` where the fit used them);
* ``method``, ``status``, ``converged``, ``cost``; ``channels`` fitted and their ``noise_std``;
  ``integrator`` (name for :func:`diffship.integrators.get_integrator` and description);
* ``data_ranges`` (``{channel: [min, max]}`` of the training runs: what the fit has seen);
* ``initial_states`` per run (``state_names`` order) and ``operating_point``: the mean of
  every channel over the first second of each training run (speed ``u`` [m/s], propeller
  ``n`` [rev/s], ...), which :mod:`diffship.predict` uses as its default approach condition;
* ``data``: provenance of every training run — file, SHA-256 of the file, samples, time step,
  duration, rudder sign in the source, resampling — and ``ship`` (length and model scale where
  known).

A command that stopped without a fit (every start diverged) writes, where it was asked for a fit file, a document
of the same schema with ``usable: false``, a FAILED ``verdict`` and ``error`` (:func:`stopped_document`), which
:func:`load_fit` refuses with that error.

Angles are radians and every value SI, as everywhere in diffship. Writing is
:func:`save_fit`; reading is :func:`load_fit` (a :class:`LoadedFit` with the model rebuilt from
the registry) or, for the parameter values only, ``Model.from_fit(path)``.
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
import hashlib
import json
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from .data import Run
from .steering import measured_helm_rate
from .errors import DataError
from .integrators import RK4, AbstractIntegrator, Diffrax, Tsit5, get_integrator
from .models import MODELS, AbstractModel
from .models.terms import base_of, terms_of, with_terms
from .params import check_values

if TYPE_CHECKING:  # type hints only
    from .fit.result import FitResult

__all__ = ["SCHEMA", "LoadedFit", "check_params", "fit_document", "fit_warnings", "integrator_name", "load_fit",
           "save_fit", "stopped_document"]

SCHEMA = "diffship.fit/1"


def integrator_name(integ: AbstractIntegrator) -> dict[str, Any]:
    """``{"name": ..., "options": ...}`` such that ``get_integrator(name, **options)`` rebuilds ``integ``."""
    hold = {"hold": integ.hold} if getattr(integ, "hold", "linear") != "linear" else {}
    if isinstance(integ, Diffrax):
        name = "diffrax-tsit5" if type(integ.solver).__name__ == "Tsit5" else "diffrax-rk4"
        return {"name": name, "options": {"substeps": int(integ.substeps), **({} if integ.unroll else {"unroll": False}),
                                          **hold}}
    if isinstance(integ, Tsit5):
        return {"name": "tsit5", "options": {"rtol": float(integ.rtol), "atol": float(integ.atol), **hold}}
    if isinstance(integ, RK4):
        return {"name": "rk4", "options": {"substeps": int(integ.substeps), **hold}}
    return {"name": getattr(integ, "name", "unknown"), "options": hold}


def registry_key(model: AbstractModel) -> str | None:
    """The ``MODELS`` key that rebuilds ``model``'s structure (same class and parameters), if any."""
    keys = [model.name] + [k for k in MODELS if k != model.name]
    for k in keys:
        if k not in MODELS:
            continue
        try:
            m = MODELS[k]()
        except Exception:  # noqa: BLE001, S112  (a registry entry that cannot be built is no match)
            continue
        if type(m) is type(model) and m.param_names == model.param_names and m.input_names == model.input_names:
            return k
    return None


def _sha256(path: Path) -> str | None:
    try:
        return hashlib.sha256(path.read_bytes()).hexdigest()
    except OSError:
        return None


def _provenance(run: Run) -> dict[str, Any]:
    meta = run.metadata
    src = meta.get("source")
    p = Path(src) if isinstance(src, str) and src != "DataFrame" else None
    return {"run": run.name, "file": p.name if p else src, "path": str(p.resolve()) if p and p.exists() else None,
            "sha256": _sha256(p) if p and p.exists() else None, "samples": run.n, "dt": run.dt,
            "duration": run.duration, "channels": list(run.channel_names),
            "rudder_sign_in_source": meta.get("rudder_sign_in_source"),
            "resampled_dt": meta.get("resampled_dt"), "degrees_converted": list(meta.get("degrees_converted", ())),
            "simulated": bool(meta.get("simulated", False)),
            **({"log": {k: meta[k] for k in ("map", "frame", "sources", "gaps", "segment", "time_origin", "holds")
                        if k in meta}} if "sources" in meta else {})}  # runs read from logs (diffship.logs)


def _operating_point(runs: Sequence[Run], first_s: float = 1.0) -> dict[str, float]:
    """Mean of each channel over the first ``first_s`` seconds, averaged over the runs."""
    acc: dict[str, list[float]] = {}
    for run in runs:
        sel = run.time <= run.t0 + first_s
        for c in run.channel_names:
            acc.setdefault(c, []).append(float(np.mean(run[c][sel])))
    out = {c: float(np.mean(v)) for c, v in acc.items() if len(v) == len(runs)}
    if "u" not in out and all(r.has("x0", "y0") for r in runs) and runs:
        speeds = []  # no surge speed measured: the speed over ground of the track's first seconds (first_s ≥ 3 s)
        for run in runs:
            sel = run.time <= run.t0 + max(first_s, 3.0)
            x, y, t = np.asarray(run["x0"])[sel], np.asarray(run["y0"])[sel], np.asarray(run.time)[sel]
            if len(t) >= 3 and t[-1] > t[0]:
                speeds.append(float(np.hypot(x[-1] - x[0], y[-1] - y[0]) / (t[-1] - t[0])))
        if len(speeds) == len(runs):
            out["u"] = float(np.mean(speeds))
    return out


def _ranges(runs: Sequence[Run]) -> dict[str, list[float]]:
    """``{channel: [min, max]}`` over the training runs (what the fit has seen)."""
    out: dict[str, list[float]] = {}
    for run in runs:
        for c in run.channel_names:
            a = np.asarray(run[c])
            lo, hi = out.get(c, [math.inf, -math.inf])
            out[c] = [min(lo, float(a.min())), max(hi, float(a.max()))]
    return out


def fit_document(result: FitResult, runs: Sequence[Run] = (), *, registry: str | None = None,
                 extra: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """The fit-file document of ``result`` (``runs``: the training runs, for provenance)."""
    model = result.model
    units = {p.name: p.unit for p in model.PARAMS}
    cov = None
    if result.covariance is not None:
        cov = {"names": list(result.free), "matrix": np.asarray(result.covariance, dtype=np.float64).tolist(),
               "units": "products of the parameters' units"}
    x0 = {"state_names": list(model.state_names),
          "runs": {n: np.asarray(x, dtype=np.float64).tolist() for n, x in zip(result.run_names, result.initial_states)}}
    scales = sorted({float(r.metadata["model_scale"]) for r in runs if "model_scale" in r.metadata})
    length = float(model.L) if hasattr(model, "L") else None
    doc = {
        "schema": SCHEMA,
        "created": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        "model": {"name": model.name, "registry": registry or registry_key(base_of(model)),
                  "class": type(model).__name__, "states": list(model.state_names), "inputs": list(model.input_names),
                  "outputs": list(model.output_names),
                  **({"terms": list(terms_of(model))} if terms_of(model) else {})},
        "method": result.method,
        "status": result.status,
        "outcome": result.outcome,
        "usable": bool(result.usable),
        "converged": bool(result.converged),
        "cost": float(result.cost),
        "params": {n: float(v) for n, v in result.params.items()},
        "units": units,
        "free": list(result.free),
        "fixed": {n: float(v) for n, v in result.params.items() if n not in result.free},
        "stderr": {n: float(v) for n, v in result.stderr.items()},
        "covariance": cov,
        "priors": result.info.get("priors"),
        "channels": list(result.channels),
        "noise_std": dict(result.noise_std),
        "channel_scales": {k: float(v) for k, v in (result.channel_scales or {}).items()},
        "integrator": {**integrator_name(result.integrator), "description": result.integrator.describe()},
        "initial_states": x0,
        "operating_point": _operating_point(runs) if runs else {},
        "helm_rate": measured_helm_rate(runs) if "delta" in model.input_names else None,
        "data_ranges": _ranges(runs),
        "ship": {"length_m": length, "model_scale": scales[0] if len(scales) == 1 else None},
        "data": [_provenance(r) for r in runs],
        "messages": list(result.messages),
        "conventions": "SI units, angles in rad, starboard-positive rudder (diffship.data)",
    }
    if extra:
        doc.update(extra)
    return doc


def stopped_document(message: str, model_name: str, registry: str | None = None) -> dict[str, Any]:
    """The fit file of a command that stopped without a fit (``message``: why, e.g. the model diverges from every
    start): schema ``diffship.fit/1`` with ``usable: false``, the verdict FAILED and ``error``, so that no fit file
    of an earlier command is left where this one was asked to write; :func:`load_fit` refuses it, naming the error."""
    return {"schema": SCHEMA, "created": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
            "model": {"name": model_name, "registry": registry or model_name}, "error": message, "usable": False,
            "converged": False, "status": message,
            "verdict": {"label": "FAILED", "usable": False, "reasons": [message], "runs": [], "unidentified": [],
                        "on_bound": []}}


def _json_default(o):
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    return str(o)


def save_fit(result: FitResult, path: str | Path, runs: Sequence[Run] = (), *, registry: str | None = None,
             extra: Mapping[str, Any] | None = None) -> Path:
    """Write ``result`` as a fit file (``"schema": "diffship.fit/1"``); returns the path."""
    path = Path(path)
    if path.parent and not path.parent.exists():
        path.parent.mkdir(parents=True, exist_ok=True)
    doc = fit_document(result, runs, registry=registry, extra=extra)
    path.write_text(json.dumps(doc, indent=2, default=_json_default, allow_nan=True))
    return path


@dataclasses.dataclass(frozen=True, eq=False)
class LoadedFit:
    """A fit read back from a fit file.

    Attributes:
        model: the model with the fitted parameter values.
        params, free, fixed, stderr, units, priors: as in the file.
        covariance: covariance of ``free`` (``covariance_names`` order), or ``None``.
        integrator: the integrator the fit was made with (rebuilt by name).
        initial_states: ``{run: state vector}``.
        operating_point: mean channel values at the start of the training runs.
        data_ranges: ``{channel: [min, max]}`` over the training runs.
        ship: ``{"length_m", "model_scale"}`` where known.
        data: provenance of the training runs.
        path: the file read; ``document``: the whole JSON document.
    """

    model: AbstractModel
    method: str
    status: str
    converged: bool
    params: dict[str, float]
    free: tuple[str, ...]
    fixed: dict[str, float]
    stderr: dict[str, float]
    covariance: np.ndarray | None
    covariance_names: tuple[str, ...]
    units: dict[str, str]
    priors: dict[str, Any] | None
    channels: tuple[str, ...]
    integrator: AbstractIntegrator
    initial_states: dict[str, np.ndarray]
    operating_point: dict[str, float]
    data_ranges: dict[str, list[float]]
    ship: dict[str, Any]
    data: tuple[dict[str, Any], ...]
    path: Path
    document: dict[str, Any]
    #: the fit's channel scales (the output-error weights; the initial-state rule of its metrics), or empty
    channel_scales: dict[str, float] = dataclasses.field(default_factory=dict)

    @property
    def has_covariance(self) -> bool:
        """A covariance with finite entries (intervals can be drawn from it)."""
        return self.covariance is not None and bool(np.all(np.isfinite(self.covariance)))

    def summary(self) -> str:
        lines = [f"fit of {self.model.name} ({self.method.replace('_', ' ')}, {self.status}) from {self.path}"]
        for n in self.free:
            se = self.stderr.get(n, math.nan)
            lines.append(f"  {n:>10s} = {self.params[n]: .6g} ± {se:.3g} {self.units.get(n, '')}".rstrip())
        return "\n".join(lines)


def fit_warnings(fit: LoadedFit) -> list[str]:
    """What a user of a fit file must be told before using it: a fit labelled FAILED (not usable), not
    converged, with unidentified parameters, parameters on a bound or training runs it does not follow (the verdict
    ``python -m diffship.fit`` recorded, :mod:`diffship.usability`)."""
    doc = fit.document
    v = doc.get("verdict") or {}
    out = []
    if doc.get("usable") is False or v.get("usable") is False:
        why = "; ".join(v.get("reasons", ())) or doc.get("status", "")
        out.append(f"WARNING: this fit is labelled FAILED ({why}): do not use these values; predictions from it "
                   "are not supported")
    elif not fit.converged:
        out.append(f"warning: the fit did NOT converge ({fit.status}): treat these predictions with care")
    for w in v.get("unidentified", ()):
        out.append(f"warning: parameter not identified by the data: {w}")
    for b in v.get("on_bound", ()):
        out.append(f"warning: parameter on its bound: {b}")
    runs = v.get("runs", ())
    if runs:
        out.append("warning: runs the fit does not follow: " + "; ".join(
            f"{r['kind']} run {r['run']} ({r['channel']}" + (f" from t = {r['from_s']:.0f} s" if r.get('from_s') is not None
                                                              and math.isfinite(r['from_s']) else "") + ")"
            for r in runs))
    return out


def read_document(path: str | Path) -> dict[str, Any]:
    """The JSON document of a fit file, schema checked (:class:`DataError` naming the file otherwise)."""
    path = Path(path)
    try:
        doc = json.loads(path.read_text())
    except FileNotFoundError:
        raise DataError(f"{path}: fit file not found; write one with python -m diffship.fit ... --out DIR "
                        "(DIR/fit.json) or --save FILE") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise DataError(f"{path}: not a readable JSON fit file ({exc})") from None
    schema = doc.get("schema") if isinstance(doc, dict) else None
    if schema != SCHEMA:
        hint = (" (this is the --json report of a fit; the fit file is --out DIR/fit.json or --save FILE)"
                if isinstance(doc, dict) and "methods" in doc else "")
        raise DataError(f"{path}: schema {schema!r} is not {SCHEMA!r}{hint}")
    if doc.get("error"):  # written by a command that stopped without a fit (stopped_document)
        raise DataError(f"{path}: holds no fit: the command that wrote it stopped without one ({doc['error']})")
    return doc


def check_params(path: Path, doc: dict[str, Any], model: AbstractModel) -> None:
    """``params`` holds a finite number for every parameter of ``model`` and nothing else; ``free`` and the
    covariance name parameters of it (a :class:`DataError` naming the file and the parameter otherwise)."""
    params = doc.get("params")
    check_values(str(path), params, model.param_names, model.name)
    cov = doc.get("covariance")
    names = [*doc.get("free", ()), *(cov.get("names", ()) if isinstance(cov, dict) else ())]
    if (bad := [n for n in names if n not in params]):
        raise DataError(f"{path}: free parameter {bad[0]!r} has no value in 'params' (model {model.name})")
    if cov is not None:
        k = len(cov.get("names", ())) if isinstance(cov, dict) else -1
        try:
            ok = np.asarray(cov["matrix"], dtype=np.float64).shape == (k, k)
        except (KeyError, TypeError, ValueError):
            ok = False
        if not ok:
            raise DataError(f"{path}: 'covariance' must be null or {{\"names\": [...], \"matrix\": a square "
                            "matrix of numbers, one row per name}; correct it or fit again")


def load_fit(path: str | Path, model: AbstractModel | None = None) -> LoadedFit:
    """Read a fit file; the model is rebuilt from the registry (or from ``model``, a template of
    the same structure) with the fitted parameter values."""
    path = Path(path)
    doc = read_document(path)
    if not isinstance(doc.get("model"), dict):
        raise DataError(f"{path}: no 'model' entry ({{\"name\", \"registry\", ...}}); write fit files with "
                        "python -m diffship.fit ... --out DIR (DIR/fit.json) or --save FILE")
    key = doc["model"].get("registry")
    if model is None:
        if key not in MODELS:
            raise DataError(f"{path}: model {doc['model'].get('name')!r} is not in the model registry; pass a "
                            "model of the same structure: load_fit(path, model=...)")
        model = MODELS[key]()
        model = with_terms(model, doc["model"].get("terms") or ())  # a discovered structure (diffship.discover)
    inputs = doc["model"].get("inputs")
    if inputs is not None and tuple(inputs) != tuple(model.input_names):
        raise DataError(f"{path}: the fitted model has inputs {tuple(inputs)}, model {model.name} here has "
                        f"{model.input_names}; pass a model of the same structure: load_fit(path, model=...)")
    check_params(path, doc, model)
    model = model.with_params(doc["params"])
    cov = doc.get("covariance")
    integ = doc.get("integrator") or {}
    try:
        integrator = get_integrator(integ.get("name", "diffrax-rk4"), **integ.get("options", {}))
    except (ValueError, TypeError) as exc:
        raise DataError(f"{path}: integrator {integ!r} cannot be rebuilt ({exc})") from None
    x0 = doc.get("initial_states") or {"runs": {}}
    return LoadedFit(
        model=model, method=doc.get("method", ""), status=doc.get("status", ""), converged=bool(doc.get("converged")),
        params=dict(doc["params"]), free=tuple(doc.get("free", ())), fixed=dict(doc.get("fixed", {})),
        stderr=dict(doc.get("stderr", {})),
        covariance=np.asarray(cov["matrix"], dtype=np.float64) if cov else None,
        covariance_names=tuple(cov["names"]) if cov else (),
        units=dict(doc.get("units", {})), priors=doc.get("priors"), channels=tuple(doc.get("channels", ())),
        integrator=integrator,
        initial_states={k: np.asarray(v, dtype=np.float64) for k, v in x0.get("runs", {}).items()},
        operating_point=dict(doc.get("operating_point", {})), data_ranges=dict(doc.get("data_ranges", {})),
        ship=dict(doc.get("ship", {})),
        data=tuple(doc.get("data", ())), path=path, document=doc,
        channel_scales={k: float(v) for k, v in (doc.get("channel_scales") or {}).items()},
    )
