"""Prediction-error method: the EKF against a linear Kalman filter written out in NumPy, agreement
with output error on calm-water data, and the gain over output error with process noise.

The disturbed runs come from a NumPy Nomoto simulator in this file (Ornstein–Uhlenbeck yaw
disturbance, Euler–Maruyama with 10 substeps), sharing nothing with the filter under test."""

import math

import jax.numpy as jnp
import numpy as np
import pytest

from diffship.data import Run
from diffship.fit import KalmanSmoother, OutputErrorOptions, fit_equation_error, fit_output_error
from diffship.fit.prediction_error import PredictionErrorOptions, ekf, fit_prediction_error
from diffship.integrators import RK4
from diffship.models import Nomoto1
from diffship.preprocess import Filter
from diffship.synthetic import rudder_sequence

DEG = math.pi / 180
TRUTH = dict(K=0.2, T1=8.0, delta0=0.01)
SENSOR = {"psi": 0.5 * DEG, "r": 0.2 * DEG}


def _linear_kf(A, B, x0, P0, q_var, r_var, ts, us, ys):
    """Textbook linear KF for x' = A x + B u with the RK4 step written out (first-order-hold u)."""
    n = A.shape[0]
    eps, logdet = [], []
    x, P = x0.copy(), P0.copy()
    for k in range(len(ts)):
        S = P + np.diag(r_var)  # H = I
        L = np.linalg.cholesky(S)
        e = ys[k] - x
        eps.append(np.linalg.solve(L, e))
        logdet.append(2 * np.sum(np.log(np.diag(L))))
        K = P @ np.linalg.inv(S)
        x = x + K @ e
        P = (np.eye(n) - K) @ P @ (np.eye(n) - K).T + K @ np.diag(r_var) @ K.T
        h = (ts[k + 1] - ts[k]) if k + 1 < len(ts) else ts[-1] - ts[-2]
        u0, u1 = us[k], us[min(k + 1, len(ts) - 1)]
        um = 0.5 * (u0 + u1)
        f = lambda xx, u: A @ xx + B * u  # noqa: E731
        k1 = f(x, u0)
        k2 = f(x + 0.5 * h * k1, um)
        k3 = f(x + 0.5 * h * k2, um)
        k4 = f(x + h * k3, u1)
        x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        hA = h * A
        Phi = np.eye(n) + hA + hA @ hA / 2 + hA @ hA @ hA / 6 + hA @ hA @ hA @ hA / 24
        P = Phi @ P @ Phi.T + np.diag(q_var) * h
    return np.asarray(eps), np.asarray(logdet)


def test_ekf_on_a_linear_model_is_the_linear_kalman_filter():
    m = Nomoto1(K=0.2, T1=8.0, delta0=0.0)
    rng = np.random.default_rng(0)
    ts = np.arange(0.0, 20.0, 0.1)
    us = 0.1 * np.sin(0.3 * ts)
    ys = np.stack([0.05 * np.sin(0.2 * ts), 0.01 * np.cos(0.2 * ts)], 1) + rng.normal(0, [0.01, 0.002], (ts.size, 2))
    q_var, r_var = np.array([0.0, 1e-6]), np.array([1e-4, 4e-6])
    x0, P0 = np.array([0.01, 0.0]), np.diag([1e-4, 1e-6])
    fp = ekf(m.vector_field, m.observe, RK4(), (True, False), jnp.asarray(q_var), jnp.asarray(r_var), jnp.asarray(ts),
             jnp.asarray(us[:, None]), jnp.asarray(ys), jnp.ones(ts.size, dtype=bool), jnp.asarray(x0), jnp.asarray(P0))
    A = np.array([[0.0, 1.0], [0.0, -1 / 8.0]])
    B = np.array([0.0, 0.2 / 8.0])
    eps, logdet = _linear_kf(A, B, x0, P0, q_var, r_var, ts, us, ys)
    np.testing.assert_allclose(np.asarray(fp.eps), eps, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(np.asarray(fp.logdet), logdet, rtol=1e-10, atol=1e-9)


def _nomoto_numpy(seed, duration=90.0, dt=0.1, sigma_w=0.0, tau=8.0):
    """Two zigzag-like runs of T r' + r = K(δ + δ0) + w, w Ornstein–Uhlenbeck [rad/s], with sensor noise."""
    K, T, d0 = TRUTH["K"], TRUTH["T1"], TRUTH["delta0"]
    rng = np.random.default_rng(seed)
    runs = []
    for i, (amp, period) in enumerate(((10 * DEG, 20.0), (-20 * DEG, 30.0))):
        t = np.arange(0.0, duration + 0.5 * dt, dt)
        delta = rudder_sequence(t, amp, period)
        psi, r, w = 0.0, 0.0, 0.0
        out = np.zeros((t.size, 2))
        n_sub = 10
        h = dt / n_sub
        for k in range(t.size):
            out[k] = psi, r
            for j in range(n_sub):
                dk = delta[k] if k + 1 == t.size else delta[k] + (delta[k + 1] - delta[k]) * j / n_sub
                w += -w / tau * h + sigma_w * math.sqrt(2 * h / tau) * rng.normal()
                psi, r = psi + h * r, r + h * (K * (dk + d0) + w - r) / T
        ys = out + rng.normal(0, [SENSOR["psi"], SENSOR["r"]], out.shape)
        runs.append(Run(f"z{i}", t, {"psi": ys[:, 0], "r": ys[:, 1], "delta": delta}, {"r_true": out[:, 1]}))
    return runs


def _fits(runs):
    spec = Nomoto1().spec().with_values({"K": 0.1, "T1": 12.0, "delta0": 0.0})
    o = OutputErrorOptions(estimate_x0=("psi", "r"), reference_priors=False)
    return (fit_output_error(Nomoto1(), runs, spec=spec, options=o),
            fit_prediction_error(Nomoto1(), runs, spec=spec, options=o))


def _worst(res):
    """Worst relative error of K and T1 (a slow disturbance's mean over 90 s is a rudder offset:
    delta0 is only checked against its standard error)."""
    return max(abs(res.params[n] - TRUTH[n]) / abs(TRUTH[n]) for n in ("K", "T1"))


@pytest.mark.slow  # 25–35 s on 2 cores; PEM's recovery, bounds and priors run in the default suite (test_battery)
def test_pem_agrees_with_output_error_in_calm_water_and_finds_the_sensor_noise():
    oe, pe = _fits(_nomoto_numpy(seed=1))
    assert pe.converged, pe.status
    for n in TRUTH:
        assert abs(pe.params[n] - oe.params[n]) < 0.5 * oe.stderr[n], (n, pe.params[n], oe.params[n], oe.stderr[n])
    for c, sd in SENSOR.items():
        assert abs(pe.info["measurement_sd"][c] / sd - 1) < 0.1, (c, pe.info["measurement_sd"])
    # no process noise in the data: the disturbance estimate is far below the 1.25e-3 rad/s² of the next test
    assert pe.info["process_sd"]["r"] < 1e-4


def test_pem_is_unbiased_under_process_noise_and_output_error_says_its_residuals_are_coloured():
    """Under a yaw disturbance (0.01 rad/s sd, 8 s time constant) prediction error's K, T1 are within 3
    standard errors of the truth. Output error's simulation residuals carry the integrated disturbance: they are
    coloured (HAC covariance) with few effective samples, so they weigh less in its likelihood (0.34 worst
    relative error when every sample counted as independent, 0.085 now, against prediction error's 0.098)."""
    oe, pe = _fits(_nomoto_numpy(seed=2, sigma_w=0.01))  # yaw disturbance 0.01 rad/s sd, 8 s time constant
    assert pe.converged, pe.status
    assert oe.info["covariance"].startswith("hac"), oe.info["covariance"]
    assert min(oe.info["correlation_time"].values()) > 10, oe.info["correlation_time"]  # few effective samples
    assert _worst(pe) < 0.15 and _worst(oe) < 0.15, (_worst(oe), _worst(pe))
    for n in TRUTH:
        assert abs(pe.params[n] - TRUTH[n]) < 3 * pe.stderr[n], (n, pe.params[n], pe.stderr[n])
    # the disturbance was found: w/T1 on the yaw acceleration, sd 0.01/8 rad/s²
    assert abs(pe.info["process_sd"]["r"] / (0.01 / 8.0) - 1) < 0.3, pe.info["process_sd"]


def test_pem_given_noise_and_bad_input_errors():
    runs = _nomoto_numpy(seed=3, duration=90.0)
    with pytest.raises(Exception, match="positive standard deviation"):
        PredictionErrorOptions(measurement_noise={"psi": -1.0})
    with pytest.raises(Exception, match="not states of model"):
        fit_prediction_error(Nomoto1(), runs, noise=PredictionErrorOptions(process_states=("u",)))


def test_ekf_rts_smoother_for_equation_error():
    runs = _nomoto_numpy(seed=7, sigma_w=0.01)
    smoothed, info = KalmanSmoother().apply(Nomoto1(**TRUTH), runs)
    assert abs(info["measurement_sd"]["r"] / SENSOR["r"] - 1) < 0.1, info
    for run, sm in zip(runs, smoothed):
        err = sm["r"] - run.metadata["r_true"]
        rms = float(np.sqrt(np.mean(err ** 2)))
        assert rms < 0.3 * SENSOR["r"], rms  # the smoother removes most of the gyro noise
        # and says how well it knows r: the reported sd matches the actual error within a factor 2
        assert 0.5 < rms / float(np.sqrt(np.mean(sm["sd_r"] ** 2))) < 2.0
    ee = fit_equation_error(Nomoto1(), smoothed, flt=Filter("none"))
    assert ee.converged and abs(ee.params["K"] / TRUTH["K"] - 1) < 0.1 and abs(ee.params["T1"] / TRUTH["T1"] - 1) < 0.1


def test_cli_prediction_error(tmp_path, capsys):
    from diffship.fit.cli import main

    paths = []
    for run in _nomoto_numpy(seed=1):
        p = tmp_path / f"{run.name}.csv"
        run.to_dataframe().to_csv(p, index=False)
        paths.append(str(p))
    assert main([*paths, "--model", "nomoto1", "--method", "prediction-error", "--init", "K=0.1", "T1=12",
                 "--disturbance", "auto", "--quiet", "--json", str(tmp_path / "pe.json")]) == 0
    text = capsys.readouterr().out
    assert "prediction error" in text and "estimated noise: measurement sd psi" in text
    # --disturbance auto: both processes fitted, the likelihood's choice said in the report and the JSON
    assert "chosen by the Akaike criterion of the filter's likelihood" in text
    import json

    doc = json.loads((tmp_path / "pe.json").read_text())
    choice = doc["methods"]["prediction_error"]["disturbance_choice"]
    assert set(choice) == {"ou", "wave"} and all(math.isfinite(v["aic"]) for v in choice.values())


def test_cli_equation_error_with_the_kalman_smoother(tmp_path, capsys):
    """``--filter kalman``: equation error on EKF + RTS smoothed runs, through the command line; on disturbed
    runs its parameters are no worse than with the default Butterworth, and the JSON says which filter
    and the estimated noise levels."""
    import json

    from diffship.fit.cli import main

    paths = []
    for run in _nomoto_numpy(seed=7, sigma_w=0.01):
        p = tmp_path / f"{run.name}.csv"
        run.to_dataframe().to_csv(p, index=False)
        paths.append(str(p))
    worst = {}
    for flt in ("kalman", "butter"):
        out = tmp_path / f"{flt}.json"
        assert main([*paths, "--model", "nomoto1", "--method", "equation-error", "--filter", flt, "--quiet",
                     "--json", str(out)]) == 0
        ee = json.loads(out.read_text())["methods"]["equation_error"]
        worst[flt] = max(abs(ee["params"][n] / TRUTH[n] - 1) for n in ("K", "T1"))
        if flt == "kalman":
            assert "Kalman filter + RTS smoother" in ee["filter"]
            sm = ee["smoother"]
            assert abs(sm["measurement_sd"]["r"] / SENSOR["r"] - 1) < 0.15, sm  # the gyro noise, found
            assert abs(sm["measurement_sd"]["psi"] / SENSOR["psi"] - 1) < 0.15, sm
    assert "Kalman smoother, estimated noise: measurement sd" in capsys.readouterr().out
    assert worst["kalman"] < 0.1, worst
    assert worst["kalman"] <= worst["butter"], worst


def test_the_disturbance_dominated_start_rescales_the_noise_and_maps_back_to_the_same_levels():
    """The second noise start (module docstring) puts each state's disturbance at its spread per time scale and the
    sensor noise at a tenth of the first start's; an optimum found in its parametrisation maps back to the first's
    with the same noise levels (the cost compares the two). Not tried where the user gave a noise start."""
    from diffship.fit.prediction_error import SENSOR_SHARE, _reparametrised, disturbance_start, pe_problem

    runs, model = _nomoto_numpy(seed=3, duration=30.0), Nomoto1()
    spec, o = model.spec(), OutputErrorOptions()
    for kind, t_d in (("ou", 10.0), ("wave", None)):
        po = PredictionErrorOptions(disturbance=kind)
        kernel, data, batch, _ = pe_problem(model, runs, spec, ("psi", "r"), o, po)
        alt = disturbance_start(model, kernel, data, batch, po)
        t_d = t_d or float(data.hyper0[0]) / (2 * math.pi)
        assert float(alt.q_scale[0]) * t_d > 10 * float(data.q_scale[0])  # the state's spread per time scale
        np.testing.assert_allclose(np.asarray(alt.r_scale), SENSOR_SHARE * np.asarray(data.r_scale))
        rng = np.random.default_rng(0)
        z = np.concatenate([spec.to_z(spec.values()), rng.uniform(0.01, 2.0, kernel.n_noise)])
        back = _reparametrised(z, kernel.n_theta, len(kernel.q_idx), 2, alt, data)
        for a, b in zip(kernel.noise(jnp.asarray(z), alt), kernel.noise(jnp.asarray(back), data)):
            np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=1e-12)
        given = PredictionErrorOptions(disturbance=kind, process_noise={"r": 1e-3})
        assert disturbance_start(model, kernel, data, batch, given) is None
