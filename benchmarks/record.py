"""The suite's recorder: every number goes into one long table (``all_numbers*.csv``).

* :class:`Recorder` — rows ``case, variant, method, metric, value, unit, note``; ``get`` looks a
  number up (the last one recorded), ``write_csv`` / ``read_csv`` store and reload them;
* timing and memory: :func:`timed` (wall time of one call), :func:`traced_peak` (tracemalloc
  peak of NumPy work), :func:`maxrss_mb` (the process high-water mark);
* what every case records of a fit: :func:`record_fit` (wall/compile/fit seconds, cost, ...),
  :func:`record_common` (parameter errors against a known truth, validation NRMSE per channel
  from a whole-run simulation of held-out runs, manoeuvre metric errors);
* summaries over repeats: :func:`seed_summary`, :func:`seed_stats`, :func:`convergence`.
"""

from __future__ import annotations

import csv
import math
import resource
import time
import tracemalloc
from contextlib import contextmanager

import numpy as np

from benchmarks.common.fitapi import fit_numbers
from diffship.metrics import evaluate

COLUMNS = ["case", "variant", "method", "metric", "value", "unit", "note"]
#: the method names of the CSV, in report order
METHODS = ("diffship_oe", "diffship_ee", "scipy_lm_numpy_rk4", "numpy_ols", "stlsq_sindy")


class Recorder:
    def __init__(self):
        self.rows: list[dict] = []

    def add(self, case, variant, method, metric, value, unit="", note=""):
        if isinstance(value, (bool, np.bool_)):
            value = int(bool(value))
        self.rows.append(dict(case=case, variant=variant, method=method, metric=metric,
                              value=float(value) if value is not None else math.nan, unit=unit, note=note))

    def get(self, case, variant, method, metric, default=math.nan):
        for r in reversed(self.rows):
            if (r["case"], r["variant"], r["method"], r["metric"]) == (case, variant, method, metric):
                return r["value"]
        return default

    def write_csv(self, path):
        with open(path, "w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=COLUMNS)
            w.writeheader()
            for r in self.rows:
                w.writerow({**r, "value": f"{r['value']:.8g}"})

    def read_csv(self, path):
        """Append the rows of a CSV written by :meth:`write_csv` (``--report-only``)."""
        with open(path) as fh:
            for r in csv.DictReader(fh):
                if r["metric"] == "note_open_loop":  # written by an earlier version
                    continue
                self.rows.append({**r, "value": float(r["value"]), "unit": zig_unit(r["metric"]) if
                                  r["unit"] == "deg" and r["metric"].startswith("rel_err") else r["unit"]})


# -- timing and memory ---------------------------------------------------------------------------------------
def say(msg):
    print(f"[{time.strftime('%H:%M:%S')}] {msg}", flush=True)


def timed(fn, *args, **kw):
    """``(fn(*args, **kw), wall seconds)``."""
    t = time.perf_counter()
    out = fn(*args, **kw)
    return out, time.perf_counter() - t


def maxrss_mb() -> float:
    """The process's peak resident memory so far (monotone; includes everything run before) [MB]."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # Linux: kB


@contextmanager
def traced_peak():
    """``with traced_peak() as mem: ...``; afterwards ``mem["mb"]`` is tracemalloc's peak [MB].

    tracemalloc sees Python/NumPy allocations only (not XLA buffers): for the NumPy peers.
    """
    mem = {}
    tracemalloc.start()
    try:
        yield mem
    finally:
        mem["mb"] = tracemalloc.get_traced_memory()[1] / 2**20
        tracemalloc.stop()


# -- what every case records -----------------------------------------------------------------------------------
FIT_UNITS = {"wall_s": "s", "compile_s": "s", "fit_s": "s", "cost": "", "iterations": "", "converged": "",
             "process_max_rss_mb": "MB"}
OE_KEYS = ("compile_s", "fit_s", "cost", "iterations", "converged")
EE_KEYS = ("compile_s", "fit_s")


def record_fit(rec, case, variant, method, res, wall, keys=OE_KEYS):
    """``wall_s``, the fit's ``keys`` (of :func:`benchmarks.fitapi.fit_numbers`), ``process_max_rss_mb``."""
    num = fit_numbers(res)
    rows = [("wall_s", wall)] + [(k, num[k]) for k in keys] + [("process_max_rss_mb", maxrss_mb())]
    for k, v in rows:
        rec.add(case, variant, method, k, v, FIT_UNITS[k])


def rel_errs(params, truth, names):
    return {n: abs(params[n] - truth[n]) / abs(truth[n]) for n in names if n in truth and truth[n] != 0}


def zig_unit(key):
    return "deg" if key.startswith("err_overshoot") else ""


def record_param_errors(rec, case, variant, method, params, truth, names):
    """``rel_err_<name>`` per parameter, ``max_rel_param_err``, ``rms_rel_param_err``."""
    errs = rel_errs(params, truth, names)
    for n, e in errs.items():
        rec.add(case, variant, method, f"rel_err_{n}", e)
    rec.add(case, variant, method, "max_rel_param_err", max(errs.values()))
    rec.add(case, variant, method, "rms_rel_param_err", float(np.sqrt(np.mean(np.square(list(errs.values()))))))


def record_common(rec, case, variant, method, model, val_runs, truth=None, names=(), zig=None):
    """Parameter error, validation NRMSE per channel, manoeuvre metric errors."""
    if truth is not None and names:
        record_param_errors(rec, case, variant, method, model.param_values(), truth, names)
    if val_runs:
        try:
            ev = evaluate(model, val_runs)
            for c in ev.channels:
                f = ev.fit_percent[c]
                rec.add(case, variant, method, f"val_nrmse_{c}", 1.0 - f / 100.0 if ev.ok else math.nan,
                        note="" if ev.ok else "validation simulation blew up")
        except Exception as exc:  # a peer's model may blow up on validation
            rec.add(case, variant, method, "val_nrmse_failed", 1.0, note=str(exc)[:120])
    if zig is not None:
        record_zig(rec, case, variant, method, zig(model))


def record_zig(rec, case, variant, method, metrics: dict):
    for key, val in metrics.items():
        rec.add(case, variant, method, key, val, zig_unit(key))


# -- summaries over repeats --------------------------------------------------------------------------------------
def seed_summary(rec, case, variants, methods):
    """Mean and median over noise seeds of the max relative parameter error (variant ``noise=realistic``)."""
    for m in methods:
        v = np.array([rec.get(case, var, m, "max_rel_param_err") for var in variants])
        v = v[np.isfinite(v)]
        if v.size:
            rec.add(case, "noise=realistic", m, "seeds_mean_max_rel_param_err", float(np.mean(v)), "",
                    f"mean over {v.size} noise seeds")
            rec.add(case, "noise=realistic", m, "seeds_median_max_rel_param_err", float(np.median(v)), "",
                    f"median over {v.size} noise seeds")


def seed_stats(rec, case, method):
    """Mean over the ``seed=*`` variants of (max, RMS) relative parameter error; (nan, nan, 0) if none."""
    mx, rms = [], []
    for var in sorted({r["variant"] for r in rec.rows if r["case"] == case and r["variant"].startswith("seed=")}):
        m = rec.get(case, var, method, "max_rel_param_err")
        q = rec.get(case, var, method, "rms_rel_param_err")
        if not math.isfinite(q):
            e = [r["value"] for r in rec.rows if r["case"] == case and r["variant"] == var and r["method"] == method
                 and r["metric"].startswith("rel_err_")]
            q = float(np.sqrt(np.mean(np.square(e)))) if e else math.nan
        if math.isfinite(m) and math.isfinite(q):
            mx.append(m)
            rms.append(q)
    return (float(np.mean(mx)), float(np.mean(rms)), len(mx)) if mx else (math.nan, math.nan, 0)


def log_uniform_starts(truth, names, n, seed):
    """``n`` starts drawn log-uniformly in ×0.3…×3 of the truth (sign kept)."""
    rng = np.random.default_rng(seed)
    return [{k: truth[k] * float(np.exp(rng.uniform(np.log(0.3), np.log(3.0)))) for k in names} for _ in range(n)]


def convergence(rec, case, variant, fits: dict[str, list[tuple[float, float]]], best=math.inf):
    """``fits[method] = [(cost, seconds), ...]`` from the same N starts: rate within 1 % of the best cost."""
    best = min([best] + [c for v in fits.values() for c, _ in v if math.isfinite(c)])
    for m, v in fits.items():
        ok = [math.isfinite(c) and c <= 1.01 * best for c, _ in v]
        rec.add(case, variant, m, "convergence_rate", float(np.mean(ok)), "", f"{len(v)} log-uniform x0.3..x3 starts")
        rec.add(case, variant, m, "n_starts", len(v))
        rec.add(case, variant, m, "mean_time_per_start_s", float(np.mean([s for _, s in v])), "s")
