"""Fit and judge diffship's MMG on the shipmmg peer's records (:mod:`.data`).

The peer's records (:mod:`.data`, made with numpy, scipy and shipmmg only) become diffship
:class:`~diffship.data.Run` objects (every conversion the identity; conventions in the docstring
of ``benchmarks/shipmmg_peer/data.py``); :func:`fit_variant` fits diffship's KVLCC2 MMG by output
error with the KVLCC2 study's settings; :func:`judge` flies the fitted model through the peer's
35° turning circles and held-out zigzags (:mod:`diffship.manoeuvres`, closed loop) and runs
:func:`diffship.admissibility.admissibility`. diffship is imported inside the functions, so the
peer module that re-exports these names stays free of diffship until one is used.
"""

from __future__ import annotations

import math

import numpy as np

from .data import HELM_RATE_DEG_S, NOISE_SEEDS, PEER_DT, U0, peer_params

#: Free sets: the MMG default, and every hull derivative of Y and N.
HULL = ("Yv", "Yr", "Yvvv", "Yvvr", "Yvrr", "Yrrr", "Nv", "Nr", "Nvvv", "Nvvr", "Nvrr", "Nrrr")
FREE_SETS = {"default": None, "hull": (*HULL, "Jz", "f_alpha", "R0", "delta0"), "study": "study"}
#: Fit settings (those of diffship.studies.kvlcc2): channels, sample interval, LM steps per pass.
CHANNELS, FIT_DT, MAX_STEPS = ("psi", "u", "v", "r"), 0.2, 60
#: Simulated durations [s] of the judged manoeuvres (the peer's and the fitted model's).
TURN_S, ZIGZAG_S = 120.0, 100.0


def to_run(rec: dict, name: str):
    """A peer record as a diffship Run (every conversion is the identity; see the module docstring)."""
    from diffship.data import Run

    ch = rec["channels"]
    meta = {**rec["meta"], "rudder_sign_in_source": "starboard", "reference_point": "midship",
            "units": "SI, rad, rev/s"}
    return Run(name, ch["time"], {k: v for k, v in ch.items() if k != "time"}, meta)


def _tag(rec: dict) -> str:
    m = rec["meta"]
    if m["manoeuvre"] == "zigzag":
        return f"{m['rudder_angle_deg']:g}/{m['switch_heading_deg']:g} {m['first_rudder'][0].upper()}"
    return f"turn 35 {m['first_rudder'][0].upper()}"


def fly(model, rec: dict, n: float):
    """The peer's manoeuvre ``rec`` flown by a diffship ``model`` (closed loop); None if it blows up."""
    from diffship.errors import ModelError
    from diffship.manoeuvres import turning_circle, zigzag

    m = rec["meta"]
    kw = {"inputs": {"n": n}, "rudder_rate_deg_s": HELM_RATE_DEG_S, "dt": PEER_DT, "first": m["first_rudder"]}
    x0 = model.initial_state({"u": U0})
    try:
        if m["manoeuvre"] == "zigzag":
            return zigzag(model, x0, rudder_deg=m["rudder_angle_deg"], switch_deg=m["switch_heading_deg"],
                          duration=ZIGZAG_S, **kw)
        return turning_circle(model, x0, rudder_deg=m["rudder_angle_deg"], duration=TURN_S, **kw)
    except ModelError:
        return None


def partial_turn(model, rec: dict, n: float) -> tuple[np.ndarray, np.ndarray, float]:
    """Midship track (x0, y0) of a turning circle up to its blow-up, and the blow-up time [s] (for figures)."""
    import jax.numpy as jnp

    from diffship.manoeuvres import ScheduleLaw, closed_loop

    s = 1.0 if rec["meta"]["first_rudder"] == "starboard" else -1.0
    ts = np.arange(0.0, TURN_S + 0.5 * PEER_DT, PEER_DT)
    law = ScheduleLaw(jnp.asarray([0.0]), jnp.asarray([s * math.radians(rec["meta"]["rudder_angle_deg"])]))
    u_const = jnp.asarray([0.0, n])
    xs, _, valid = closed_loop(model, law, jnp.asarray(ts), jnp.asarray(model.initial_state({"u": U0})), u_const,
                               model.input_names.index("delta"), jnp.asarray(math.radians(HELM_RATE_DEG_S)),
                               jnp.asarray(math.radians(35.0)), jnp.asarray(0.0))
    xs, valid = np.asarray(xs), np.asarray(valid)
    k = int(np.argmin(valid)) if not valid.all() else len(ts)
    i, j = model.state_names.index("x0"), model.state_names.index("y0")
    return xs[:k, i], xs[:k, j], float(ts[k - 1])


def metrics(run, rec: dict) -> dict:
    """Turning (TD, advance [m]) or zigzag (1st, 2nd overshoot [°]) metrics of a Run; NaN if none."""
    from diffship.manoeuvres import turning_metrics, zigzag_metrics

    if run is None:
        return {"TD": math.nan, "advance": math.nan, "os1": math.nan, "os2": math.nan}
    if rec["meta"]["manoeuvre"] == "turning_circle":
        tm = turning_metrics(run, length=7.0)
        return {"TD": tm.tactical_diameter, "advance": tm.advance}
    zm = zigzag_metrics(run, smooth_s=0.0)
    return {"os1": zm.first_overshoot, "os2": zm.second_overshoot}


def judge(model, fit, train: list, peer: dict, n: float) -> dict:
    """Turning circles, held-out zigzags and admissibility of a (fitted) diffship model."""
    from diffship.admissibility import admissibility
    from diffship.models.mmg import kvlcc2_mmg

    row: dict = {}
    for key, rec in peer.items():
        run = fly(model, rec, n)
        m, p = metrics(run, rec), peer_metrics(rec)
        row[f"{key}_run"] = run
        if rec["meta"]["manoeuvre"] == "turning_circle":
            row[f"{key}_blowup"] = run is None
            for k in ("TD", "advance"):
                row[f"{key}_{k}"] = m[k]
                row[f"{key}_{k}_err_pct"] = 100.0 * (m[k] - p[k]) / p[k]
        else:
            for k in ("os1", "os2"):
                row[f"{key}_{k}"] = m[k]
                row[f"{key}_{k}_err"] = m[k] - p[k]
    adm = admissibility(model, initial={"u": U0}, inputs={"n": n}, training=train, reference=kvlcc2_mmg(),
                        free=fit.free if fit is not None else (), helm_rate_deg_s=HELM_RATE_DEG_S, turn_s=TURN_S,
                        zigzag_s=ZIGZAG_S)
    row["admissible"] = adm.ok
    row["admissibility"] = adm.summary()
    row["offending"] = adm.offending
    row["blowup"] = any(v for k, v in row.items() if k.endswith("_blowup"))
    return row


_PEER_METRICS: dict = {}


def peer_metrics(rec: dict) -> dict:
    key = id(rec)
    if key not in _PEER_METRICS:
        _PEER_METRICS[key] = metrics(to_run(rec, "peer " + _tag(rec)), rec)
    return _PEER_METRICS[key]


def peer_particulars() -> dict[str, float]:
    """The peer's fixed particulars in diffship's MMG names (x_G, k_zz, x'_P, m, ρ)."""
    basic, _, rho = peer_params()
    return {"xG": basic.x_G, "kzz": math.sqrt(basic.I_zG / basic.m) / basic.L_pp, "xP": basic.x_P, "m": basic.m,
            "rho": rho}


def fit_variant(train: list, free: str, priors: bool, *, prior_rel_sd: float = 0.5, extra_free: tuple = (),
                fix: tuple = (), nrrr_upper: float | None = None, particulars: dict | None = None):
    """Output-error fit of diffship's KVLCC2 MMG (the study's settings) to the training Runs.

    ``particulars``: fixed values replacing the reference vessel's; the reference priors are
    then passed explicitly (``default_priors`` turns them off for another vessel).
    """
    import dataclasses

    from diffship.fit import OutputErrorOptions, fit_output_error
    from diffship.fit.priors import reference_priors
    from diffship.models.mmg import kvlcc2_mmg
    from diffship.params import ParamSpec

    model = kvlcc2_mmg(**(particulars or {}))
    spec = model.spec()
    if FREE_SETS[free] == "study":  # the KVLCC2 study's default: all 30 hydrodynamic coefficients
        from diffship.studies.kvlcc2 import DEFAULT_FREE
        spec = spec.only_free(list(DEFAULT_FREE))
    elif FREE_SETS[free] is not None:
        spec = spec.only_free(list(FREE_SETS[free]))
    spec = spec.free(extra_free).fix(fix)
    if nrrr_upper is not None:  # a sign constraint: N'_rrr < bound (yaw damping never turns destabilising)
        spec = ParamSpec(tuple(dataclasses.replace(p, upper=nrrr_upper) if p.name == "Nrrr" else p
                               for p in spec.params))
    runs = [r.resample(FIT_DT) for r in train]
    explicit = reference_priors(kvlcc2_mmg(), spec, prior_rel_sd) if particulars and priors else None
    opts = OutputErrorOptions(max_steps=MAX_STEPS, reference_priors=priors, prior_rel_sd=prior_rel_sd,
                              priors=explicit)
    return fit_output_error(model, runs, spec=spec, channels=CHANNELS, options=opts)


def yaw_damping_limit(p: dict) -> float:
    """r' above which ∂N'_H/∂r' = N'_r + 3 N'_rrr r'² (at v' = 0) turns positive (inf if never)."""
    return math.sqrt(-p["Nr"] / (3.0 * p["Nrrr"])) if p["Nrrr"] > 0 and p["Nr"] < 0 else math.inf


def residual_memory(fit, train: list) -> dict[str, float]:
    """Integrated autocorrelation time τ [samples] of the fit's output-error residuals, per channel.

    τ = 1 + 2 Σ_k ρ_k (summed until ρ_k first drops below 0), averaged over the runs. The fit
    weighs its N residuals as independent; with τ ≫ 1 (model-structure error, not white noise)
    the data are over-counted about τ-fold against the priors — a ±50 % prior then acts like
    one of ±50 %·√τ.
    """
    from diffship.metrics import simulate_run

    out: dict[str, list[float]] = {c: [] for c in CHANNELS}
    for run, x0 in zip((r.resample(FIT_DT) for r in train), fit.initial_states):
        ys = np.asarray(simulate_run(fit.model, run, np.asarray(x0)).ys)
        for c in CHANNELS:
            e = ys[:, fit.model.output_names.index(c)] - run[c]
            e = e - e.mean()
            acf = np.correlate(e, e, "full")[e.size - 1:] / max(float(e @ e), 1e-300)
            neg = np.nonzero(acf < 0)[0]
            out[c].append(1.0 + 2.0 * float(np.sum(acf[1:neg[0] if neg.size else acf.size])))
    return {c: float(np.mean(v)) for c, v in out.items()}


def fit_summary(fit) -> dict:
    ident = fit.info["identifiability"]
    pri = fit.info.get("priors", {})
    far = sorted(((n, v["z_from_prior"]) for n, v in pri.items()), key=lambda kv: -abs(kv[1]))[:3]
    return {"status": fit.status, "converged": fit.converged, "iterations": fit.iterations,
            "fit_s": fit.fit_seconds, "compile_s": fit.compile_seconds, "prior_note": fit.info["prior_note"],
            "params": {n: fit.params[n] for n in fit.free}, "stderr": dict(fit.stderr),
            "far_from_prior": far, "weak": [w["text"] for w in ident["weak_directions"]],
            "sign_flips": [f["name"] for f in ident["sign_flips"]], "warnings": ident["warnings"],
            "rp_crit": yaw_damping_limit({**fit.params}),
            "condition": ident["condition"]}


def variants(quick: bool) -> list[dict]:
    train = ("20/20 S",) if quick else ("10/10 S", "20/20 S")
    out = []
    for free in (("default",) if quick else ("default", "hull", "study")):
        for noise in ("none", "model-test"):
            for priors in (True, False):
                out.append({"train": train, "free": free, "priors": priors, "noise": noise, "group": "main"})
    if not quick:  # two more noise seeds for the default free set
        out += [{"train": train, "free": "default", "priors": priors, "noise": noise, "group": "main"}
                for noise in list(NOISE_SEEDS)[1:] for priors in (True, False)]
    if not quick:  # what would fix the default-prior fit (diagnosis, same clean data)
        base = {"train": train, "free": "default", "priors": True, "noise": "none", "group": "remedy"}
        out += [{**base, "remedy": "N'_rrr < 0 (sign constraint)", "nrrr_upper": 0.0},
                {**base, "remedy": "priors ±20 %", "prior_rel_sd": 0.2},
                {**base, "remedy": "wake C1, C2± free", "extra_free": ("C1", "C2_plus", "C2_minus")},
                {**base, "remedy": "N'_vvr, N'_rrr fixed at reference", "fix": ("Nvvr", "Nrrr")},
                {**base, "remedy": "peer's x_G, k_zz, x'_P, m, ρ (fixed)", "particulars": peer_particulars()},
                {**base, "remedy": "+ 35/5 zigzag in training", "train": (*train, "35/5 S")},
                {**base, "remedy": "wake C1, C2± free and N'_rrr < 0", "extra_free": ("C1", "C2_plus", "C2_minus"),
                 "nrrr_upper": 0.0},
                {**base, "remedy": "priors ±50 %/√τ (τ: residual memory of the default fit)", "tau_scaled": True}]
    return out


ZIGZAGS = {"10/10 S": (10, 10, "starboard"), "20/20 S": (20, 20, "starboard"), "35/5 S": (35, 5, "starboard")}
