"""HUMS indexes on signals with known answers: spectra, fidelity ratios, lost motion,
online = offline, and clear errors when a log lacks a signal."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bench import BenchError
from bench.hums import indexes as I
from bench.signals.trace import Trace

DT = 1e-3


@pytest.mark.parametrize("window", ["hann", "rect", "flattop"])
def test_spectrum_reads_the_amplitude_of_an_on_bin_sine(window):
    t = np.arange(2000) * DT                     # 2 s: 0.5 Hz bins, 2 Hz on bin 4
    y = 1.3 * np.sin(2 * np.pi * 2.0 * t + 0.4) + 0.25 * np.sin(2 * np.pi * 6.0 * t) + 0.7
    f, a = I.amplitude_spectrum(y, DT, window)
    assert a[np.argmin(abs(f - 2.0))] == pytest.approx(1.3, rel=1e-6)
    assert a[np.argmin(abs(f - 6.0))] == pytest.approx(0.25, rel=1e-6)
    if window != "flattop":     # (the flat top's 10-bin lobe reaches DC from 2 Hz)
        assert a[0] == pytest.approx(0.0, abs=1e-9)  # detrended: the offset is no line


@settings(max_examples=25, deadline=None)
@given(f0=st.floats(1.4, 9.0), amp=st.floats(0.05, 5.0), phase=st.floats(0, 6.28))
def test_harmonic_amplitudes_hold_off_bin(f0, amp, phase):
    """Lobe-energy reading: within 1 % wherever the line falls between bins (the peak
    bin alone reads down to 0.85 A with a Hann window), with the harmonics >= 4 bins
    apart; an empty harmonic reads the Hann side-lobe leakage of its neighbours, < 3 %."""
    t = np.arange(3000) * DT
    y = amp * np.sin(2 * np.pi * f0 * t + phase) + 0.3 * amp * np.sin(2 * np.pi * 3 * f0 * t)
    h = I.harmonic_amplitudes(y, DT, f0, 3)
    assert h[0] == pytest.approx(amp, rel=0.01)
    assert h[1] == pytest.approx(0.0, abs=0.03 * amp)
    assert h[2] == pytest.approx(0.3 * amp, rel=0.02)


def test_harmonics_above_nyquist_are_nan_and_short_windows_refused():
    t = np.arange(1000) * DT
    h = I.harmonic_amplitudes(np.sin(2 * np.pi * 200 * t), DT, 200.0, 4)
    assert h[0] == pytest.approx(1.0, rel=1e-3) and np.isnan(h[-1])
    with pytest.raises(BenchError, match="shorter than one period"):
        I.harmonic_amplitudes(np.sin(t), DT, 0.5, 3)


def test_fidelity_ratios_have_the_thesis_signs():
    t = np.arange(2000) * DT
    x_n = 0.5e-3 * np.sin(2 * np.pi * 2 * t)
    x = 0.9 * x_n                                   # real nut moves 10 % less
    assert I.cp(x_n, x) == pytest.approx(1 / 0.9)   # > 1 with lost motion
    assert I.mean_error(x_n, x) == pytest.approx(0.1 * np.mean(np.abs(x_n)))
    i_n = np.sin(2 * np.pi * 2 * t)
    i = 1.5 * i_n                                   # real motor needs 50 % more current
    assert I.ci(i_n, i) == pytest.approx(1 / 1.5)  # < 1
    assert I.peak_ratio(i_n, i) == pytest.approx(1.5)
    # ratio of integrals stays finite where the pointwise ratio of eq. 6.6 diverges
    assert math.isfinite(I.ci(i_n, i_n)) and I.ci(i_n, i_n) == pytest.approx(1.0)


def test_harmonic_ci_ignores_broadband_noise():
    rng = np.random.default_rng(3)
    t = np.arange(5000) * DT
    i_n = np.sin(2 * np.pi * 2 * t)
    noisy = i_n + 0.3 * rng.standard_normal(len(t))
    assert I.ci(i_n, noisy) < 0.9                     # noise pulls plain Ci down ...
    assert I.ci_harmonic(i_n, noisy, 500) == pytest.approx(1.0, abs=0.02)   # ... not this
    assert I.ci_harmonic(i_n, 2 * i_n, 500) == pytest.approx(0.5)


def test_friction_current_rejects_the_inertial_part():
    t = np.arange(2000) * DT
    w = 30 * np.cos(2 * np.pi * 2 * t)
    i = -1.1 * np.sin(2 * np.pi * 2 * t) + 0.07 * np.sign(w)   # inertia + Coulomb
    assert I.friction_current(i, w) == pytest.approx(0.07, abs=2e-3)


def _hysteresis_trace(width_m: float, n: int = 3000) -> Trace:
    """Motor angle of a sine; the nut follows through a dead band of `width_m` (the play
    operator), seen by the LVDT model; no noise."""
    from bench.hums.indexes import Kinematics, MotionStream
    kin = Kinematics()
    t = np.arange(n) * DT
    ang = 2.5 * np.sin(2 * np.pi * 2 * t)                # motor rad
    speed = np.gradient(ang, DT)
    enc = ang * kin.travel_per_motor_rad_m
    nut = np.zeros(n)
    for k in range(1, n):
        nut[k] = min(max(nut[k - 1], enc[k] - width_m / 2), enc[k] + width_m / 2)
    # the LVDT's dynamics on the nut, as MotionStream models them for the encoder
    ms = MotionStream(DT, kin)
    lvdt_like = ms.push(nut / kin.travel_per_motor_rad_m, np.zeros(n), speed)[0]
    return Trace({"t_s": t, "motor_angle_rad": ang, "motor_speed_rad_s": speed,
                  "position_m": lvdt_like})


@pytest.mark.parametrize("width_um", [0.0, 20.0, 140.0])
def test_lost_motion_measures_a_known_dead_band(width_um):
    assert I.lost_motion(_hysteresis_trace(width_um * 1e-6)) * 1e6 == pytest.approx(
        width_um, abs=0.05 + 0.01 * width_um)


def _sine_pair(n=6000, degrade=0.0, seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * DT
    sp = 0.5e-3 * np.sin(2 * np.pi * 2 * t)
    cols = {"t_s": t, "setpoint_position_m": sp, "setpoint_speed_rad_s": 0 * t,
            "mode": np.ones(n), "position_m": sp * (1 - 0.1 * degrade),
            "current_a": np.sin(2 * np.pi * 2 * t) * (1 + degrade)
            + 0.05 * rng.standard_normal(n),
            "motor_speed_rad_s": 30 * np.cos(2 * np.pi * 2 * t),
            "motor_angle_rad": 2.4 * np.sin(2 * np.pi * 2 * t)}
    nom = dict(cols, position_m=sp, current_a=np.sin(2 * np.pi * 2 * t))
    return Trace(cols, {"fundamental_hz": 2.0}), Trace(nom, {"fundamental_hz": 2.0})


def test_period_indexes_cover_whole_periods_and_match_online():
    real, nom = _sine_pair()
    rows = list(I.period_indexes(real, nom))
    assert len(rows) == 12 and rows[1].t_start_s == pytest.approx(0.5)
    assert all(r.ci == pytest.approx(1.0, abs=0.01) for r in rows)
    # the online monitor (own nominal from the set-points, pushed in odd chunks) gives
    # the same per-period numbers as period_indexes over the same nominal
    from bench.hums import monitor as M
    live = I.OnlineHums(0.5, M.THESIS_FITTED_GAIN * M.THESIS_SET_GAIN_V_PER_M)
    got = []
    for k0 in range(0, len(real), 777):
        got += live.push({k: v[k0:k0 + 777] for k, v in real.columns.items()})
    offline_nom = M.nominal_for(real, M.THESIS_FITTED_GAIN * M.THESIS_SET_GAIN_V_PER_M)
    ref = list(I.period_indexes(real, offline_nom))
    assert len(got) == len(ref) == 12
    for a, b in zip(got, ref, strict=True):
        assert a.ci == pytest.approx(b.ci, rel=1e-12)
        assert a.cp == pytest.approx(b.cp, rel=1e-12)
        assert a.lost_motion_m == pytest.approx(b.lost_motion_m, rel=1e-9, abs=1e-15)
        assert a.harmonics_a == pytest.approx(b.harmonics_a, rel=1e-9)


def test_missing_signals_give_a_clear_error():
    real, nom = _sine_pair()
    no_current = Trace({k: v for k, v in real.columns.items() if k != "current_a"})
    with pytest.raises(BenchError, match=r"current indexes.*current_a"):
        I.compare(no_current, nom, need=("current",))
    # position indexes alone still work on that log
    ix = I.compare(no_current, nom, need=("position",))
    assert ix.cp == pytest.approx(1.0, abs=1e-12) and math.isnan(ix.ci)
    no_pos = Trace({k: v for k, v in real.columns.items() if k != "position_m"})
    with pytest.raises(BenchError, match="position_m"):
        list(I.period_indexes(no_pos, nom))
    nan_current = Trace(dict(real.columns, current_a=np.full(len(real), np.nan)))
    with pytest.raises(BenchError, match="current_a"):
        I.compare(nan_current, nom, need=("current",))
    with pytest.raises(BenchError, match="differ in length"):
        I.compare(real.window(0, 1.0), nom)
    with pytest.raises(BenchError, match="needs the signal"):
        I.OnlineHums(0.5).push({"t_s": [0.0]})
