"""The independent actuator's physics, compiled: one SYNC period per `advance`, sensors
sampled by `sense`. Written apart from `plant_rt` on purpose (docs/independent-plant.md
gives every equation with its number, I1-I14, cited below).

State (`x`): motor angle and speed, nut position and speed, LuGre bristle deflection,
phase current, current-PI integrator, LVDT demodulator and extra-lag filters, the mean
external force of the last period, the drive's held voltage and the logged current
sensor's filter. I15-I17 are physics switched on only for the final check of the gap
diagnosis (docs/gap-results.md): off in every development run.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from indie_plant.params import IDX

TH, OM, XN, VN, ZB, CUR, CINT, LV1, LV2, FLAST, VOLT, CFIL = range(12)
NX = 12

_KT, _KE, _R, _L, _J = (IDX[n] for n in ("kt_nm_per_a", "ke_v_s_per_rad", "resistance_ohm",
                                          "inductance_h", "inertia_kg_m2"))
_PP, _RIP, _COG, _NCOG = (IDX[n] for n in ("pole_pairs", "ripple", "cogging_nm",
                                           "cogging_per_rev"))
_VDC, _ILIM, _CBW = IDX["supply_v"], IDX["current_limit_a"], IDX["current_bw_hz"]
_VFRAC = IDX["voltage_frac"]
_RATIO, _LEAD, _MN, _CN = (IDX[n] for n in ("ratio", "lead_m", "nut_mass_kg",
                                            "nut_viscous_n_s_per_m"))
_KH, _HC, _PRE, _BL = (IDX[n] for n in ("hertz_n_per_m15", "hc_damping_s_per_m", "preload_n",
                                        "backlash_m"))
_TC, _MU, _SR, _WS = (IDX[n] for n in ("coulomb_nm", "screw_friction", "static_ratio",
                                       "stribeck_rad_s"))
_S0, _S1, _S2 = IDX["bristle_nm_per_rad"], IDX["bristle_damping"], IDX["viscous_nm_s_per_rad"]
_FS, _VS = IDX["friction_scale"], IDX["viscous_scale"]
_IBITS, _IRANGE, _INOISE, _IOFF = (IDX[n] for n in ("current_adc_bits", "current_range_a",
                                                    "current_noise_a", "current_offset_a"))
_ENC, _WIN, _EGAIN = IDX["encoder_counts"], IDX["speed_window"], IDX["encoder_gain"]
_LBITS, _LRANGE, _LNOISE, _LTAU, _LTAU2 = (IDX[n] for n in (
    "lvdt_bits", "lvdt_range_m", "lvdt_noise_m", "lvdt_tau_s", "lvdt_extra_lag_s"))
_LGAIN, _LOFF = IDX["lvdt_gain"], IDX["lvdt_offset_m"]
_FNOISE, _FSTEP = IDX["load_noise_n"], IDX["load_step_n"]
_DELAY, _T, _NSUB, _NOISE = (IDX[n] for n in ("sensor_delay_periods", "sync_period_s",
                                              "substeps", "noise"))
_LDELAY = IDX["lvdt_delay_periods"]
_RIPF, _SEAL, _CFILT = IDX["friction_ripple"], IDX["seal_friction_n"], IDX["current_filter_s"]
SEAL_V = 1e-4               # m/s: the seal's Coulomb force is F tanh(v / SEAL_V)
# controller vector and state (indie_plant.controller.Cascade; the law is compiled here,
# with the physics, so numba's on-disk cache never pairs stale code across files)
(C_SRC, C_KPP, C_KIP, C_KPS, C_KIS, C_WLIM, C_ILIM, C_EVERY, C_T, C_TRAVEL) = range(10)
NCV = 10
S_IPOS, S_ISPD, S_HELD = range(3)
NCS = 3
SOURCE_LVDT, SOURCE_ENCODER = 0.0, 1.0
CURRENT_PI_EVERY = 5        # the drive's current PI runs every 5th sub-step (20 kHz)
HIST = 64                   # sensor history ring (delay + speed window)


@njit(cache=True)
def contact_force(d: float, ddot: float, kh: float, alpha: float) -> float:
    """Hertzian contact of one nut half with Hunt-Crossley damping (I7):
    F = k_H d^1.5 (1 + alpha d'), zero when the half is unloaded (d <= 0) and never
    pulling."""
    if d <= 0.0:
        return 0.0
    f = kh * d ** 1.5 * (1.0 + alpha * ddot)
    return f if f > 0.0 else 0.0


@njit(cache=True)
def preload_deflection(preload_n: float, kh: float) -> float:
    """Deflection of each half under the preload alone (I8): d0 = (F_pr / k_H)^(2/3)."""
    return (preload_n / kh) ** (2.0 / 3.0) if preload_n > 0.0 else 0.0


@njit(cache=True)
def stribeck(w: float, tc: float, ratio: float, ws: float) -> float:
    """LuGre's steady-state friction g(w) (I10): Tc (1 + (Ts/Tc - 1) exp(-(w/ws)^2))."""
    return tc * (1.0 + (ratio - 1.0) * math.exp(-(w / ws) ** 2))


@njit(cache=True)
def lugre_update(z: float, w: float, g: float, s0: float, h: float) -> float:
    """Bristle state after `h` at speed `w` (I9, dz/dt = w - s0 |w| z / g), integrated
    exactly for constant w (the bristle pole s0 |w| / g is far beyond 1/h at speed)."""
    a = s0 * abs(w) / g
    if a * h < 1e-12:
        return z + w * h
    zss = w / a
    return zss + (z - zss) * math.exp(-a * h)


@njit(cache=True)
def motor_torque(i: float, th: float, p: np.ndarray) -> float:
    """Air-gap torque with 6th-harmonic ripple per electrical angle and cogging per
    mechanical angle (I3): kt i (1 + r cos(6 p th)) - T_cog sin(N_cog th)."""
    return (p[_KT] * i * (1.0 + p[_RIP] * math.cos(6.0 * p[_PP] * th))
            - p[_COG] * math.sin(p[_NCOG] * th))


@njit(cache=True)
def advance(x: np.ndarray, p: np.ndarray, demand_a: float, fext_n: float) -> None:
    """One SYNC period holding the current demand and the external axial force (I1-I12)."""
    # long: one compiled sub-step loop; splitting it costs a call per sub-step
    n = int(p[_NSUB])
    h = p[_T] / n
    ilim = p[_ILIM]
    dem = min(max(demand_a, -ilim), ilim) if math.isfinite(demand_a) else 0.0
    kp = 2.0 * math.pi * p[_CBW] * p[_L]              # I2: PI zero on the winding pole
    ki = 2.0 * math.pi * p[_CBW] * p[_R]
    vmax = p[_VFRAC] * p[_VDC]
    tr = p[_RATIO] * p[_LEAD] / (2.0 * math.pi)        # I5
    d0 = preload_deflection(p[_PRE], p[_KH])
    half_gap = 0.5 * p[_BL]
    s0, s1, s2 = p[_S0], p[_S1], p[_S2] * p[_VS]
    facc = 0.0
    for j in range(n):
        if j % CURRENT_PI_EVERY == 0:                  # I2: drive current PI, clamped
            e = dem - x[CUR]
            u = kp * e + x[CINT]
            uc = min(max(u, -vmax), vmax)
            if not (uc != u and e * u > 0.0):
                x[CINT] += ki * e * h * CURRENT_PI_EVERY
            x[VOLT] = uc
        w = x[OM]
        x[CUR] += h * (x[VOLT] - p[_R] * x[CUR] - p[_KE] * w) / p[_L]      # I1
        delta = x[TH] * tr - x[XN]                     # I6: screw ahead of the nut
        ddot = w * tr - x[VN]
        fa = contact_force(d0 + delta - half_gap, ddot, p[_KH], p[_HC])
        fb = contact_force(d0 - delta - half_gap, -ddot, p[_KH], p[_HC])
        fnet = fa - fb                                 # I7: axial force on the nut
        tcoul = p[_FS] * (p[_TC] + p[_MU] * (fa + fb) * tr)                # I11
        if p[_RIPF] > 0.0:     # I15: friction ripple per screw turn (final check only)
            tcoul *= 1.0 + p[_RIPF] * math.sin(x[TH] * p[_RATIO])
        g = max(stribeck(w, tcoul, p[_SR], p[_WS]), 1e-9)
        zn = lugre_update(x[ZB], w, g, s0, h)
        tf = s0 * zn + s1 * (zn - x[ZB]) / h + s2 * w  # I9: LuGre torque
        x[ZB] = zn
        tm = motor_torque(x[CUR], x[TH], p)
        x[OM] = w + h * (tm - tf - tr * fnet) / p[_J]  # I4
        x[TH] += h * x[OM]
        fseal = p[_SEAL] * math.tanh(x[VN] / SEAL_V)   # I16: rod seal (final check only)
        x[VN] += h * (fnet - fext_n - p[_CN] * x[VN] - fseal) / p[_MN]      # I12
        if p[_CFILT] > 0.0:    # I17: the current sensor's anti-alias filter (final check)
            x[CFIL] += h * (x[CUR] - x[CFIL]) / p[_CFILT]
        else:
            x[CFIL] = x[CUR]
        x[XN] += h * x[VN]
        x[LV1] += h * (x[XN] - x[LV1]) / p[_LTAU]      # I14: LVDT demodulator
        x[LV2] = x[LV1] if p[_LTAU2] <= 0.0 else x[LV2] + h * (x[LV1] - x[LV2]) / p[_LTAU2]
        facc += fext_n
    x[FLAST] = facc / n


@njit(cache=True)
def quantise(v: float, step: float, full: float) -> float:
    """An ADC: round to the step, saturate at +-full scale (I13)."""
    q = step * math.floor(v / step + 0.5) if step > 0.0 else v
    return min(max(q, -full), full)


@njit(cache=True)
def sense(x: np.ndarray, p: np.ndarray, hist: np.ndarray, k: int, rnd: np.ndarray,
          out: np.ndarray) -> None:
    """Sensors at SYNC k (I13-I14) into out = [current A, angle rad, speed rad/s, LVDT m,
    load N]: current ADC, encoder counts (delayed), speed from the counts over a window,
    LVDT ADC after its lag (delayed, and by its own transport delay on top), load cell =
    mean force of the last period."""
    nz = p[_NOISE]
    istep = 2.0 * p[_IRANGE] / 2.0 ** p[_IBITS]
    out[0] = quantise(x[CFIL] + p[_IOFF] + nz * p[_INOISE] * rnd[0], istep, p[_IRANGE])
    cpr = p[_ENC]
    ang = math.floor(x[TH] * cpr / (2.0 * math.pi)) * 2.0 * math.pi / cpr
    lstep = 2.0 * p[_LRANGE] / 2.0 ** p[_LBITS]
    lv = quantise(p[_LGAIN] * x[LV2] + p[_LOFF] + nz * p[_LNOISE] * rnd[1], lstep, p[_LRANGE])
    hist[k % HIST, 0] = ang
    hist[k % HIST, 1] = lv
    d = int(p[_DELAY])
    win = int(p[_WIN])
    kd = max(k - d, 0)
    kw = max(kd - win, 0)
    kl = max(kd - int(p[_LDELAY]), 0)
    out[1] = hist[kd % HIST, 0]
    out[3] = hist[kl % HIST, 1]
    span = max(kd - kw, 1)
    out[2] = p[_EGAIN] * (hist[kd % HIST, 0] - hist[kw % HIST, 0]) / (span * p[_T])
    out[4] = quantise(x[FLAST] + nz * p[_FNOISE] * rnd[2], p[_FSTEP], 1e9)


def initial_state() -> np.ndarray:
    """At rest, the nut at 0 and seated on its preload."""
    return np.zeros(NX)     # CFIL follows CUR from the first sub-step


def initial_history(x: np.ndarray, p: np.ndarray) -> np.ndarray:
    """A sensor history that has read the initial state forever."""
    hist = np.zeros((HIST, 2))
    out = np.zeros(5)
    sense(x, p, hist, 0, np.zeros(3), out)
    hist[:, 0] = out[1]
    hist[:, 1] = out[3]
    return hist


@njit(cache=True)
def _pi(e: float, integ: float, kp: float, ki: float, dt: float, lim: float
        ) -> tuple[float, float]:
    """PI with clamping anti-windup (integration stops while saturated outward)."""
    u = kp * e + integ
    uc = min(max(u, -lim), lim)
    if not (uc != u and e * u > 0.0):
        integ += ki * e * dt
    return uc, integ


@njit(cache=True)
def cascade_step(s: np.ndarray, c: np.ndarray, k: int, sp_pos: float, sp_spd: float,
                 mode: float, lvdt: float, angle: float, speed: float) -> float:
    """The current demand at SYNC k (mode 0 idle, 1 position, 2 speed); between samples
    the last demand is held."""
    every = int(c[C_EVERY])
    if k % every != 0:
        return s[S_HELD]
    if mode == 0.0:
        s[:] = 0.0
        return 0.0
    ts = every * c[C_T]
    lim = c[C_WLIM]
    if mode == 1.0:
        pos = lvdt if c[C_SRC] == SOURCE_LVDT else angle * c[C_TRAVEL]
        w_dem, s[S_IPOS] = _pi(sp_pos - pos, s[S_IPOS], c[C_KPP], c[C_KIP], ts, lim)
    else:
        w_dem = min(max(sp_spd, -lim), lim)
    i_dem, s[S_ISPD] = _pi(w_dem - speed, s[S_ISPD], c[C_KPS], c[C_KIS], ts, c[C_ILIM])
    s[S_HELD] = i_dem
    return i_dem


@njit(cache=True)
def run(x, p, hist, cvec, sp_pos, sp_spd, mode, fext, rnd, meas, dem):  # pragma: no cover
    """A whole run in-process (`indie_plant.generate.simulate`): at SYNC k sense, the
    cascade's demand, then one period under the demand of SYNC k-1."""
    n = len(sp_pos)
    s = np.zeros(NCS)
    out = np.zeros(5)
    applied = 0.0
    for k in range(n):
        sense(x, p, hist, k, rnd[k], out)
        meas[k, :] = out
        d = cascade_step(s, cvec, k, sp_pos[k], sp_spd[k], mode[k], out[3], out[1], out[2])
        dem[k] = d
        advance(x, p, applied, fext[k])
        applied = d
        if not np.isfinite(x[OM]):
            meas[k:, :] = np.nan
            dem[k:] = np.nan
            return k
    return n
