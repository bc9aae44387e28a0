r"""KVLCC2 (HSVA, SIMMAN 2008) zigzags: fit an MMG model on some, predict the others.

Workflow (:func:`kvlcc2_study`):

1. load the 13 free-running zigzags (:func:`diffship.data.kvlcc2_runs`; inputs ``delta`` and
   ``n``, measured ``psi, u, v, r``), split them into training and validation runs;
2. fit the MMG model (:func:`diffship.models.mmg.kvlcc2_mmg`, published KVLCC2 L7 values as
   start and for every fixed coefficient) by output error to the training runs, resampled to
   ``dt`` and cut to their first ``horizon`` seconds; free by default (:data:`DEFAULT_FREE`):
   every hydrodynamic coefficient — hull derivatives up to third order, added masses, the
   resistance R'_0, the rudder and hull–rudder interaction coefficients, the propeller wake's
   change in manoeuvring (C_1, C_2±) and a rudder offset δ_0 — each with the published value as a prior (±50 %, :mod:`diffship.fit.priors`) and the
   data weighted by their effective sample size. Zigzags alone cannot identify the terms a
   hard turn needs (N'_vvr, N'_rrr …; the identifiability report lists about fifteen poorly
   identified directions): with the priors these stay near the captive-test values while the
   data move what they do determine, so the fitted model both reproduces the zigzags and
   predicts the 35° turning circle. (Freeing only the ten parameters of
   :data:`TEN_FREE` without priors, the fit bends N'_vvr by a factor of six and flips the
   sign of N'_rrr: tactical diameter 5.6–6.5 L instead of the measured 3.1–3.3 L.)
3. predict every run two ways: *closed loop* — the fitted model flies the zigzag with the
   autopilot of :func:`diffship.manoeuvres.zigzag` (measured initial state, propeller speed,
   first side and execute time, helm rate 15.8 °/s, autopilot delay 0.28 s) — which is the
   honest forecast of the IMO metrics; and *open loop* — simulation with the measured rudder
   (its reversals happen when the *measured* heading hit ±ψ_s, so only its first overshoot is
   comparable);
4. compute the IMO metrics with the same function on measured and simulated runs
   (:func:`diffship.manoeuvres.zigzag_metrics`).

Measured (four training and four validation zigzags, ``tests/studies/test_kvlcc2.py``): first
overshoots of the validation runs within 0.85°; 35° turning circle tactical diameter 3.17 L
starboard, 3.10 L port (free-running measurements: 3.1–3.3 L). Without the wake correction free
(30 coefficients) the turn is as good (3.08 / 3.25 L) but the 10/10-S first overshoot misses by
1.31°: the manoeuvring wake sets the propeller race over the rudder, which a zigzag feels.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence

import numpy as np
import pandas as pd

from ..data import Run, kvlcc2_runs
from ..errors import DataError
from ..fit import FitResult, OutputErrorOptions, fit_output_error
from ..metrics import simulate_run
from ..simulate import initial_state
from ..integrators import Diffrax
from ..manoeuvres import first_execute, zigzag, zigzag_metrics
from ..models.mmg import MMG, kvlcc2_mmg

__all__ = [
    "AUTOPILOT_DELAY_S", "DEFAULT_CHANNELS", "DEFAULT_FREE", "DEFAULT_TRAIN", "TEN_FREE", "HELM_RATE_DEG_S", "KVLCC2Study",
    "autopilot_delays", "closed_loop_run", "kvlcc2_study", "open_loop_run", "predict_zigzags", "study_fit",
]

#: Training zigzags: small and large rudder, 5° and 10° switch (all starboard-first; both
#: port-first runs are left for validation).
DEFAULT_TRAIN = ("Z_10_05", "Z_20_05", "Z_35_05", "Z_20_10_S")
#: The MMG model's own default free set (ten parameters).
TEN_FREE = tuple(MMG().spec().free_names)  # Yv Yr Nv Nr Nvvr Nrrr Jz f_alpha R0 delta0
#: Free MMG parameters of the default fit: every hydrodynamic and interaction coefficient and the
#: propeller wake's manoeuvring correction C1, C2± (the geometry, mass, straight-run wake and
#: open-water curve stay fixed), each held by its published value as a prior.
DEFAULT_FREE = ("R0", "Xvv", "Xvr", "Xrr", "Xvvvv", "Yv", "Yr", "Yvvv", "Yvvr", "Yvrr", "Yrrr",
                "Nv", "Nr", "Nvvv", "Nvvr", "Nvrr", "Nrrr", "mx", "my", "Jz", "tR", "aH", "xH", "eps",
                "kappa", "lR", "gammaR_minus", "gammaR_plus", "f_alpha", "delta0", "C1", "C2_plus", "C2_minus")
#: Fitted channels (``None``: every measured model output except positions).
DEFAULT_CHANNELS = ("psi", "u", "v", "r")
#: Helm rate of the HSVA model tests [°/s] (data README).
HELM_RATE_DEG_S = 15.8
#: Delay of the HSVA zigzag autopilot between the heading reaching ±ψ_s and the rudder starting
#: to move [s]: median of every reversal but the first in the 13 runs (:func:`autopilot_delays`;
#: 0.25–0.33 s in the runs with switch angles of 5° and 10° and large rudder angles).
AUTOPILOT_DELAY_S = 0.28


@dataclasses.dataclass(frozen=True, eq=False)
class KVLCC2Study:
    """Result of :func:`kvlcc2_study`.

    Attributes:
        fit: the output-error fit (its ``model`` is the fitted MMG).
        train, validate: test names (e.g. ``"Z_10_10_S"``).
        table: one row per run: role, measured and predicted overshoots [°] (closed loop:
            ``*_cl``; open loop with the measured rudder: ``first_ol``) and their errors.
        measured, closed_loop, open_loop: ``{test: Run}``.
    """

    fit: FitResult
    train: tuple[str, ...]
    validate: tuple[str, ...]
    table: pd.DataFrame
    measured: dict[str, Run]
    closed_loop: dict[str, Run]
    open_loop: dict[str, Run]

    def max_first_overshoot_error(self, kind: str = "cl") -> float:
        """Largest |predicted − measured| first overshoot over the validation runs [°]."""
        v = self.table[self.table.role == "validate"]
        return float(np.max(np.abs(v[f"first_{kind}"] - v["first_meas"])))


def _test(run: Run) -> str:
    return run.name.replace("KVLCC2_", "")


def open_loop_run(model: MMG, run: Run) -> Run:
    """The run with the model's channels replaced by a simulation driven by the measured inputs."""
    sol = simulate_run(model, run, initial_state(model, run))
    ys = np.asarray(sol.ys)
    return run.with_channels(**{c: ys[:, j] for j, c in enumerate(model.output_names)})


def autopilot_delays(run: Run, threshold_deg: float = 0.3) -> list[float]:
    """Per reversal: time from the heading reaching ±ψ_s to the rudder leaving its plateau [s]."""
    zm = zigzag_metrics(run, smooth_s=0.0)
    t, d = run.time, np.degrees(run["delta"])
    side = 1.0 if zm.first_rudder == "starboard" else -1.0
    out = []
    for k, te in enumerate(zm.execute_times):
        sgn = side * (1.0 if k % 2 == 0 else -1.0)
        i = int(np.searchsorted(t, te - 3.0))
        moved = np.nonzero(sgn * (d[i] - d[i:]) > threshold_deg)[0]
        if moved.size:
            out.append(float(t[i + moved[0]] - te))
    return out


def closed_loop_run(model: MMG, run: Run, *, dt: float = 0.1, duration: float = 100.0,
                    helm_rate_deg_s: float = HELM_RATE_DEG_S, delay_s: float = AUTOPILOT_DELAY_S) -> Run:
    """The zigzag of ``run`` flown by ``model`` with the autopilot (same start, side, angles)."""
    meta = run.metadata
    i0, _ = first_execute(run)
    x0 = initial_state(model, run)
    return zigzag(model, x0, rudder_deg=float(meta["rudder_angle_deg"]), switch_deg=float(meta["switch_heading_deg"]),
                  first=str(meta["first_rudder"]), inputs={"n": float(np.mean(run["n"]))}, duration=duration, dt=dt,
                  t_execute=float(run.time[i0] - run.time[0]), rudder_rate_deg_s=helm_rate_deg_s,
                  max_rudder_deg=35.0, switch_delay_s=delay_s, integrator=Diffrax(), name=f"{_test(run)} predicted")


def predict_zigzags(model: MMG, runs: Sequence[Run], roles: dict[str, str] | None = None, *, dt: float = 0.1,
                    duration: float = 100.0) -> tuple[pd.DataFrame, dict, dict]:
    """Overshoot table (measured vs closed-loop and open-loop predictions) for zigzag runs."""
    rows, cl, ol = [], {}, {}
    for run in runs:
        k = _test(run)
        meas = zigzag_metrics(run)
        cl[k] = closed_loop_run(model, run, dt=dt, duration=duration)
        ol[k] = open_loop_run(model, run.resample(dt).slice(None, run.time[0] + duration))
        pc, po = zigzag_metrics(cl[k]), zigzag_metrics(ol[k])
        rows.append(dict(test=k, role=(roles or {}).get(k, ""), rudder_deg=meas.rudder_deg, switch_deg=meas.switch_deg,
                         first_side=meas.first_rudder, first_meas=meas.first_overshoot, first_cl=pc.first_overshoot,
                         first_ol=po.first_overshoot, second_meas=meas.second_overshoot,
                         second_cl=pc.second_overshoot))
    df = pd.DataFrame(rows)
    df["err_first_cl"] = df.first_cl - df.first_meas
    df["err_first_ol"] = df.first_ol - df.first_meas
    df["err_second_cl"] = df.second_cl - df.second_meas
    return df, cl, ol


def study_fit(train: Sequence[Run], *, free: Sequence[str] = DEFAULT_FREE,
              channels: Sequence[str] | None = DEFAULT_CHANNELS, max_steps: int = 60, model: MMG | None = None,
              progress: Callable[[str], None] | None = None) -> FitResult:
    """The study's MAP output-error fit on given training runs (already resampled and cut).

    The fit :func:`kvlcc2_study` makes, on runs the caller prepares (e.g. logs with an injected
    effect, ``benchmarks/withheld_real.py``): the published KVLCC2 values as start, ``free`` held by
    their ±50 % priors (the default on the reference vessel), ``channels`` fitted.
    """
    model = model or kvlcc2_mmg()
    spec = model.spec().only_free(list(free))
    return fit_output_error(model, list(train), spec=spec, channels=channels, progress=progress,
                            options=OutputErrorOptions(max_steps=max_steps))


def kvlcc2_study(*, train: Sequence[str] = DEFAULT_TRAIN, validate: Sequence[str] | None = None,
                 free: Sequence[str] = DEFAULT_FREE, channels: Sequence[str] | None = DEFAULT_CHANNELS,
                 dt: float = 0.2, horizon: float = 100.0, max_steps: int = 60,
                 root=None, model: MMG | None = None, progress: Callable[[str], None] | None = None) -> KVLCC2Study:
    """Fit the MMG model to training zigzags and predict the overshoots of all (see module docstring).

    Args:
        train: training tests (names as ``"Z_10_05"``; see the data README).
        validate: validation tests (default: every other test).
        free: free MMG parameters (every other one is fixed at the published value).
        channels: measured channels fitted.
        dt: sample interval of the fit [s] (the data are 20 Hz); horizon: fitted seconds per run.
        max_steps: Levenberg–Marquardt steps per pass.
        root: folder of the tidy CSVs (default: the shared data folder).
        model: start model (default :func:`~diffship.models.mmg.kvlcc2_mmg`).
    """
    runs = {_test(r): r for r in kvlcc2_runs(root)}
    unknown = [k for k in (*train, *(validate or ())) if k not in runs]
    if unknown:
        raise DataError(f"unknown KVLCC2 test(s) {unknown}; available: {sorted(runs)}")
    validate = tuple(validate) if validate is not None else tuple(k for k in runs if k not in train)
    tr = [runs[k].resample(dt).slice(None, runs[k].time[0] + horizon) for k in train]
    fit = study_fit(tr, free=free, channels=channels, max_steps=max_steps, model=model, progress=progress)
    roles = {**{k: "train" for k in train}, **{k: "validate" for k in validate}}
    table, cl, ol = predict_zigzags(fit.model, [runs[k] for k in (*train, *validate)], roles)
    return KVLCC2Study(fit=fit, train=tuple(train), validate=validate, table=table,
                       measured={k: runs[k] for k in roles}, closed_loop=cl, open_loop=ol)
