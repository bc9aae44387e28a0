"""The NumPy signal processing (zero-phase Butterworth filter, Welch spectrum) gives SciPy's numbers, and a fit
command does not import scipy.signal (1.4 s of every process)."""

import subprocess
import sys

import numpy as np
import pytest
from scipy import signal

from diffship.dsp import butter_lowpass, detrend_linear, filtfilt, lfilter, sosfilt_zi, welch


@pytest.mark.parametrize("order", [1, 2, 3, 4, 6])
@pytest.mark.parametrize("wn", [0.005, 0.1, 0.8])
def test_the_sections_are_scipys_butterworth(order, wn):
    sos = butter_lowpass(order, wn)
    ref = signal.butter(order, wn, output="sos")
    # the same filter: the same frequency response (section order and pairing may differ)
    w = np.linspace(0.0, np.pi, 64)
    _, h = signal.sosfreqz(sos, worN=w)
    _, h_ref = signal.sosfreqz(ref, worN=w)
    assert np.max(np.abs(h - h_ref)) < 1e-12
    assert abs(h[0] - 1.0) < 1e-12  # unit gain at zero frequency
    np.testing.assert_allclose(sosfilt_zi(sos)[0], signal.sosfilt_zi(sos)[0], rtol=1e-10, atol=1e-12)


@pytest.mark.parametrize("order, wn", [(4, 0.1), (4, 0.02), (2, 0.3), (3, 0.005)])
@pytest.mark.parametrize("n", [6, 128, 129, 3001])
def test_filtfilt_is_scipys_on_random_walks(order, wn, n):
    x = np.cumsum(np.random.default_rng(n).normal(size=n)) + 5.0
    pad = min(3 * (order + 1), n - 1)
    y = filtfilt(butter_lowpass(order, wn), x, pad)
    ref = signal.sosfiltfilt(signal.butter(order, wn, output="sos"), x, padlen=pad)
    assert np.max(np.abs(y - ref)) <= 1e-11 * np.max(np.abs(ref))
    b, a = signal.butter(order, wn)  # the polynomial form of the same filter, where it keeps its digits
    if wn >= 0.1:
        assert np.max(np.abs(y - signal.filtfilt(b, a, x, padlen=pad))) <= 1e-11 * np.max(np.abs(ref))


def test_lfilter_runs_the_recurrence_across_blocks_from_a_given_state():
    b, a = signal.butter(2, 0.2)
    x = np.random.default_rng(1).normal(size=1000)  # several blocks and a partial last one
    zi = np.array([0.3, -0.1])
    np.testing.assert_allclose(lfilter(b, a, x, zi), signal.lfilter(b, a, x, zi=zi)[0], rtol=0, atol=1e-12)


def test_a_constant_passes_unchanged_and_a_short_pad_is_refused():
    x = np.full(50, 2.5)
    np.testing.assert_allclose(filtfilt(butter_lowpass(4, 0.1), x, 15), x, rtol=1e-12)
    with pytest.raises(ValueError, match="pad of 15"):
        filtfilt(butter_lowpass(4, 0.1), x[:10], 15)
    with pytest.raises(ValueError, match="cut-off"):
        butter_lowpass(4, 1.2)


@pytest.mark.parametrize("n", [32, 255, 256, 257, 3001])
def test_welch_of_the_detrended_signal_is_scipys(n):
    k = np.arange(n)
    y = np.cumsum(np.random.default_rng(n).normal(size=n)) + np.sin(0.3 * k) + 0.02 * k + 4.0
    np.testing.assert_allclose(detrend_linear(y), signal.detrend(y), rtol=0, atol=1e-12 * np.max(np.abs(y)))
    f, P = welch(detrend_linear(y), 20.0, min(256, n))
    f_ref, P_ref = signal.welch(signal.detrend(y), fs=20.0, nperseg=min(256, n))
    np.testing.assert_allclose(f, f_ref, rtol=1e-14)
    assert np.max(np.abs(P - P_ref)) <= 1e-12 * np.max(P_ref)
    # white noise of variance σ² has the one-sided density 2σ²/fs
    e = np.random.default_rng(n + 1).normal(0.0, 0.3, 20 * n)
    _, Pw = welch(e, 20.0, 256)
    assert np.mean(Pw[1:-1]) == pytest.approx(2 * 0.3 ** 2 / 20.0, rel=0.1)


def test_initial_states_and_the_automatic_cut_off_do_not_import_scipy_signal():
    code = ("import sys, numpy as np\n"
            "import pandas as pd\n"
            "from diffship.data import Run\n"
            "from diffship.models import get_model\n"
            "from diffship.simulate import initial_state\n"
            "t = np.arange(0, 60, 0.1)\n"
            "run = Run.from_dataframe(pd.DataFrame({'time': t, 'psi': 0.1 * np.sin(0.1 * t), 'r': 0.01 * np.cos(0.1 * t),"
            " 'delta': 0.1 * np.sign(np.sin(0.05 * t))}), name='r0')\n"
            "x0 = initial_state(get_model('nomoto1'), run)\n"
            "assert np.all(np.isfinite(x0))\n"
            "from diffship.preprocess import auto_cutoff\n"
            "assert 0 < auto_cutoff(np.sin(0.1 * t) + 0.01 * np.cos(3 * t), 0.1) < 5\n"
            "print('scipy.signal' in sys.modules)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.strip() == "False"
