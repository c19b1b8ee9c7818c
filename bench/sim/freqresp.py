"""Measured frequency responses of the simulated loops (rows P5-P7).

Each point is a simulation with a sinusoidal reference; the response and the reference
are projected on the test frequency over whole periods after the transient (a lock-in
measurement), so the numbers include everything the loop really has: PWM, sample and
hold, the bus's period of delay, sensor filters, friction. Open-loop responses come
from the measured closed loop of a unity-feedback loop: L = T / (1 - T), with T the
response from the reference to the *sensor* the loop is closed on.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from bench.profiles.catalog import Profile
from bench.signals.trace import MODE_POSITION, MODE_SPEED
from bench.sim.control import ControllerParams
from bench.sim.harness import simulate
from plant_rt import kernel as K
from plant_rt.model import Plant
from plant_rt.params import PlantParams


@dataclass
class FreqResponse:
    """A measured frequency response T(f) and the margins of L = T/(1-T)."""
    name: str
    f_hz: np.ndarray
    T: np.ndarray                          # closed loop, reference -> sensor
    amplitude: float = float("nan")
    notes: dict[str, float] = field(default_factory=dict)

    @property
    def L(self) -> np.ndarray:
        return self.T / (1.0 - self.T)

    def bandwidth_hz(self) -> float:
        """First frequency where |T| falls 3 dB below its low-frequency value.

        Kept here: python-control's `bandwidth()` takes a parametric model (its DC gain),
        not measured points."""
        mag = 20 * np.log10(np.abs(self.T))
        ref = mag[0]
        below = np.where(mag < ref - 3.0)[0]
        if len(below) == 0:
            return float("nan")
        i = below[0]
        if i == 0:
            return float(self.f_hz[0])
        # interpolate in log f between the two points around -3 dB
        f0, f1 = np.log(self.f_hz[i - 1]), np.log(self.f_hz[i])
        m0, m1 = mag[i - 1] - ref + 3.0, mag[i] - ref + 3.0
        return float(np.exp(f0 + (f1 - f0) * m0 / (m0 - m1)))

    def resonance(self) -> tuple[float, float]:
        """(frequency Hz, peak dB) of the largest |T| above its low-frequency value (an argmax
        over measured points: nothing for a library to do)."""
        mag = 20 * np.log10(np.abs(self.T))
        i = int(np.argmax(mag))
        return float(self.f_hz[i]), float(mag[i] - mag[0])

    def margins(self) -> tuple[float, float, float]:
        """(phase margin deg, gain margin dB, crossover Hz) of L = T/(1-T).

        Crossings come from python-control's `stability_margins` on the measured FRD
        (cubic-spline interpolation between the measured points); the crossover is the
        first |L| = 1 crossing, the gain margin is read at the first phase crossing of
        -180 deg (mod 360) at or above half the crossover (a phase wrap well below the
        crossover is the integrator's, not a margin). PM is in [-180, 180)."""
        import control  # ~1-3 s to import, and it imports pyplot: only when margins are asked for
        w = 2 * math.pi * self.f_hz
        frd = control.frd(self.L, w, smooth=True)
        gms, pms, _, w180, wc, _ = control.stability_margins(frd, returnall=True)
        pm, fc = float("nan"), float("nan")
        if len(wc):
            pm, fc = float(pms[0]), float(wc[0] / (2 * math.pi))
        for g, w_ in zip(gms, w180, strict=True):
            if math.isnan(fc) or w_ / (2 * math.pi) >= fc * 0.5:
                return pm, float(20 * np.log10(g)), fc
        return pm, float("inf"), fc


def lockin(y: np.ndarray, t: np.ndarray, f: float) -> complex:
    """Complex amplitude of y at frequency f (y ~ Re(A e^{j 2 pi f t})).

    Kept here: a one-bin DFT at an arbitrary frequency over whole periods (the test
    frequency is not an FFT bin, so numpy.fft / scipy.signal have no call for it)."""
    e = np.exp(-2j * math.pi * f * t)
    return complex(2.0 * np.mean(y * e))


def _window(t: np.ndarray, f: float, settle_cycles: float, cycles: float) -> np.ndarray:
    """Samples of whole periods after the transient: a time selection (rectangular over
    whole periods), not a spectral taper, so not a `scipy.signal.get_window` window."""
    t0 = settle_cycles / f
    return (t >= t0) & (t < t0 + cycles / f)


def current_loop(params: PlantParams | None = None, freqs: np.ndarray | None = None,
                 amplitude_a: float = 2.0, bias_a: float = 0.0,
                 rate_hz: float = 50000.0) -> FreqResponse:
    """Drive current loop: demand -> current sensor, demand updated at `rate_hz`.

    The current demand reaches the drive at the SYNC rate on the bus (1 kHz), too slow
    to excite an 800 Hz loop; the drive's own loop is measured here with its demand
    held at `rate_hz` (sample-and-hold corrected), as a drive vendor would measure it.
    """
    params = params or PlantParams()
    freqs = np.geomspace(20, 5000, 28) if freqs is None else np.asarray(freqs)
    ts = 1.0 / rate_hz
    T = []
    for f in freqs:
        plant = Plant(params)
        # a period shorter than the SYNC minimum: set the kernel's sub-step count directly
        pv = plant.param_vector.copy()
        dt = pv[K.P_DT]
        nsub = max(1, int(round(ts / dt)))
        pv[K.P_NSUB] = nsub
        tper = nsub * dt
        settle, cyc = max(3.0, 0.02 * f), max(5.0, 0.02 * f)
        n = int(math.ceil((settle + cyc) / f / tper)) + 2
        t = np.arange(n) * tper
        dem = bias_a + amplitude_a * np.sin(2 * math.pi * f * t)
        u = np.tile(plant.inputs(0.0), (n, 1))
        u[:, K.U_IDEM] = dem
        out = np.zeros((n, K.NO))
        xs = np.zeros((n, K.NX))
        K.run_open(plant.x, pv, u, out, xs)
        tm = t + tper                    # states are at the end of each period
        w = _window(tm, f, settle, cyc)
        y = lockin(xs[w, K.IM], tm[w], f)
        # the held demand: its fundamental lags the samples by half a period (ZOH)
        wz = 2 * math.pi * f * tper
        r = lockin(dem[w], t[w], f) * np.exp(-0.5j * wz) * (np.sinc(wz / (2 * math.pi)))
        T.append(y / r)
    return FreqResponse("current", freqs, np.array(T), amplitude_a)


def speed_loop(params: PlantParams | None = None, cparams: ControllerParams | None = None,
               freqs: np.ndarray | None = None, amplitude_rad_s: float = 20.0,
               bias_rad_s: float = 0.0) -> FreqResponse:
    """ECU speed loop over the bus timing: speed set-point -> encoder speed."""
    params = params or PlantParams()
    freqs = np.geomspace(1, 300, 24) if freqs is None else np.asarray(freqs)
    T = []
    for f in freqs:
        settle, cyc = max(2.0, 0.1 * f), max(4.0, 0.1 * f)
        dur = (settle + cyc) / f + 0.002
        w_ = 2 * math.pi * f

        def speed(t: np.ndarray, w_: float = w_) -> np.ndarray:
            return bias_rad_s + amplitude_rad_s * np.sin(w_ * t)
        prof = Profile("speed-sine", MODE_SPEED, dur, lambda t: np.zeros_like(t), speed)
        tr = simulate(prof, params, cparams)
        w = _window(tr.t, f, settle, cyc)
        y = lockin(tr["motor_speed_rad_s"][w], tr.t[w], f)
        r = lockin(tr["setpoint_speed_rad_s"][w], tr.t[w], f)
        T.append(y / r)
    return FreqResponse("speed", freqs, np.array(T), amplitude_rad_s)


def position_loop(params: PlantParams | None = None, cparams: ControllerParams | None = None,
                  freqs: np.ndarray | None = None, amplitude_m: float = 1e-3) -> FreqResponse:
    """Position loop: position set-point -> LVDT, at a given command amplitude."""
    params = params or PlantParams()
    freqs = np.geomspace(0.5, 60, 22) if freqs is None else np.asarray(freqs)
    T = []
    for f in freqs:
        settle, cyc = 2.0, 4.0
        dur = (settle + cyc) / f + 0.002
        w_ = 2 * math.pi * f

        def position(t: np.ndarray, w_: float = w_) -> np.ndarray:
            return amplitude_m * np.sin(w_ * t)
        prof = Profile("pos-sine", MODE_POSITION, dur, position, lambda t: np.zeros_like(t))
        tr = simulate(prof, params, cparams)
        w = _window(tr.t, f, settle, cyc)
        y = lockin(tr["position_m"][w], tr.t[w], f)
        r = lockin(tr["setpoint_position_m"][w], tr.t[w], f)
        T.append(y / r)
    return FreqResponse(f"position {amplitude_m * 1e3:g} mm", freqs, np.array(T), amplitude_m)
