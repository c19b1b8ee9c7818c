"""A generic position/speed cascade for logs run under a controller the bench does not
know ("for an unknown controller, its gains: a generic position/speed cascade
with saturation and sample time, fitted in closed loop").

The structure is the usual one of a servo drive, stated here as data (`Cascade`):

- position loop on a chosen sensor (the LVDT, or the encoder angle as nut travel,
  theta tau p / 2 pi): P, or PI with clamping anti-windup (`plant_rt.pi`), its output the
  speed demand saturated at +- the speed limit; in speed mode the logged speed set-point;
- speed PI on the encoder speed, its output the current demand saturated at +- the
  current limit;
- a sample time of a whole number of SYNC periods: the law runs at every `every`-th SYNC
  and its demand is held in between; the drive applies a demand one period later, as
  over the bus (`bench.sim.loop`).

`bench.gap.calibrate.fit_cascade` fits the gains and the speed limit by closed-loop
least squares on a healthy log, for each position sensor and sample time, and keeps the
best; `bench.gap.resim.closed_loop` runs the plant under it when `Drive.cascade` is set.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from bench.sim.loop import kernel_advance, kernel_measure, kernel_truth, no_prepare, run_loop
from plant_rt import kernel as K
from plant_rt.jit import njit
from plant_rt.pi import clamped_pi

# the law's vector
(G_SRC, G_KPP, G_KIP, G_KPS, G_KIS, G_WLIM, G_ILIM, G_EVERY, G_T, G_TRAVEL) = range(10)
NG = 10
# its state: position integral, speed integral, held demand, SYNC counter
GC_IPOS, GC_ISPD, GC_HELD, GC_COUNT = range(4)
NGC = 4
SOURCES = ("lvdt", "encoder")


@dataclass(frozen=True)
class Cascade:
    """A generic cascade (SI): position source (SOURCES), position PI gains ((rad/s)/m,
    (rad/s)/(m s); ki 0: P), speed PI gains (A s/rad, A/rad), speed limit (rad/s),
    current limit (A), sample time in SYNC periods."""
    source: str
    kp_pos: float
    ki_pos: float
    kp_spd: float
    ki_spd: float
    speed_limit_rad_s: float
    current_limit_a: float
    every_periods: int

    def vector(self, sync_period_s: float, travel_per_rad: float) -> np.ndarray:
        """The compiled law's vector (`cascade_control`)."""
        v = np.zeros(NG)
        v[G_SRC] = SOURCES.index(self.source)
        v[G_KPP], v[G_KIP], v[G_KPS], v[G_KIS] = (self.kp_pos, self.ki_pos, self.kp_spd,
                                                  self.ki_spd)
        v[G_WLIM], v[G_ILIM] = self.speed_limit_rad_s, self.current_limit_a
        v[G_EVERY], v[G_T], v[G_TRAVEL] = self.every_periods, sync_period_s, travel_per_rad
        return v

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Cascade:
        """The cascade of a `describe()` dict (other keys ignored)."""
        return cls(str(d["source"]), float(d["kp_pos"]), float(d["ki_pos"]),
                   float(d["kp_spd"]), float(d["ki_spd"]), float(d["speed_limit_rad_s"]),
                   float(d["current_limit_a"]), int(d["every_periods"]))

    def describe(self) -> dict[str, float | str]:
        """The gains with their units and the corner frequencies of the integrals."""
        d: dict[str, float | str] = {k: v for k, v in asdict(self).items()}
        d["position_integral_zero_hz"] = self.ki_pos / self.kp_pos / (2 * math.pi) \
            if self.kp_pos else 0.0
        d["speed_integral_zero_hz"] = self.ki_spd / self.kp_spd / (2 * math.pi) \
            if self.kp_spd else 0.0
        d["units"] = ("kp_pos (rad/s)/m, ki_pos (rad/s)/(m s), kp_spd A s/rad, ki_spd A/rad, "
                      "limits rad/s and A, sample time in SYNC periods")
        return d


@njit(inline="always", error_model="numpy")
def cascade_control(c, kvec, ref, kk, meas, kd):  # pragma: no cover - compiled
    """The generic cascade (module doc) at this SYNC: (position set-point m, speed
    set-point rad/s, mode) = ref[kk]; the measurement row kd (delayed samples)."""
    return cascade_rows(c, kvec, ref, kk, meas, kd, kd)


@njit(inline="always", error_model="numpy")
def cascade_rows(c, kvec, ref, kk, meas, kl, ke):  # pragma: no cover - compiled
    """`cascade_control` with the LVDT read from measurement row kl and the encoder
    (angle and speed) from row ke: sensors delayed apart (`bench.gap.delays`)."""
    count = c[GC_COUNT]
    c[GC_COUNT] = count + 1.0
    every = kvec[G_EVERY]
    if count - every * math.floor(count / every) != 0.0:
        return c[GC_HELD]
    mode = ref[kk, 2]
    pos = meas[kl, K.M_POS] if kvec[G_SRC] == 0.0 else meas[ke, K.M_ANGLE] * kvec[G_TRAVEL]
    speed = meas[ke, K.M_SPEED]
    if mode == 0.0 or not (math.isfinite(pos) and math.isfinite(speed)):
        c[GC_IPOS] = 0.0
        c[GC_ISPD] = 0.0
        c[GC_HELD] = 0.0
        return 0.0
    ts = every * kvec[G_T]
    lim = kvec[G_WLIM]
    if mode == 1.0:
        w_dem, c[GC_IPOS] = clamped_pi(ref[kk, 0] - pos, c[GC_IPOS], kvec[G_KPP],
                                       kvec[G_KIP], ts, lim)
    else:
        w_dem = min(max(ref[kk, 1], -lim), lim)
    i_dem, c[GC_ISPD] = clamped_pi(w_dem - speed, c[GC_ISPD], kvec[G_KPS], kvec[G_KIS], ts,
                                   kvec[G_ILIM])
    c[GC_HELD] = i_dem
    return i_dem


@njit(cache=True, nogil=True, error_model="numpy")
def cascade_on_plant(x, p, s, aux, u, noise, ref, kvec, cstate, ndelay, meas_out, dem_out,
                     diag_out, truth_out, applied, k0):  # pragma: no cover - compiled
    """The generic cascade on the full plant."""
    return run_loop(no_prepare, kernel_measure, kernel_truth, kernel_advance,
                    cascade_control, x, p, s, aux, u, noise, ref, kvec, cstate, ndelay,
                    meas_out, dem_out, diag_out, truth_out, applied, k0)


@njit(cache=True, error_model="numpy")
def replay(kvec, ref, meas):  # pragma: no cover - compiled
    """The law's demand at every SYNC from logged inputs: ref (n, 3) set-points and mode,
    meas (n, plant_rt.kernel.NM) the logged sensor samples as the controller saw them."""
    n = ref.shape[0]
    c = np.zeros(NGC)
    out = np.empty(n)
    for k in range(n):
        out[k] = cascade_control(c, kvec, ref, k, meas, k)
    return out


def logged_inputs(cols: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """(ref, meas) of `replay` from logged columns (setpoint_position_m,
    setpoint_speed_rad_s, mode, position_m, motor_angle_rad, motor_speed_rad_s)."""
    n = len(cols["mode"])
    ref = np.column_stack([np.nan_to_num(np.asarray(cols[c], float)) for c in (
        "setpoint_position_m", "setpoint_speed_rad_s", "mode")])
    meas = np.zeros((n, K.NM))
    meas[:, K.M_POS] = cols["position_m"]
    meas[:, K.M_ANGLE] = cols["motor_angle_rad"]
    meas[:, K.M_SPEED] = cols["motor_speed_rad_s"]
    return ref, meas


@njit(cache=True, error_model="numpy")
def replay_one_step(kvec, ref, meas, dem):  # pragma: no cover - compiled
    """As `replay`, but after each sample whose logged demand `dem` is not saturated the
    speed integral is set to the value that gives that demand (one-step-ahead
    prediction: a wrong gain does not accumulate over the log). The position integral
    runs on the logged samples as in `replay`."""
    n = ref.shape[0]
    out = np.empty(n)
    ipos = 0.0
    ispd = 0.0
    held = 0.0
    every = kvec[G_EVERY]
    ts = every * kvec[G_T]
    lim, ilim = kvec[G_WLIM], kvec[G_ILIM]
    for k in range(n):
        if k - every * math.floor(k / every) != 0.0:
            out[k] = held
            continue
        mode = ref[k, 2]
        pos = meas[k, K.M_POS] if kvec[G_SRC] == 0.0 else meas[k, K.M_ANGLE] * kvec[G_TRAVEL]
        if mode == 0.0:
            ipos = 0.0
            ispd = 0.0
            held = 0.0
            out[k] = 0.0
            continue
        if mode == 1.0:
            w_dem, ipos = clamped_pi(ref[k, 0] - pos, ipos, kvec[G_KPP], kvec[G_KIP], ts, lim)
        else:
            w_dem = min(max(ref[k, 1], -lim), lim)
        e = w_dem - meas[k, K.M_SPEED]
        held, ispd = clamped_pi(e, ispd, kvec[G_KPS], kvec[G_KIS], ts, ilim)
        out[k] = held
        if abs(dem[k]) < 0.999 * ilim:
            ispd = dem[k] - kvec[G_KPS] * e + kvec[G_KIS] * e * ts
    return out
