"""Where the gap lies: by signal, by path, by regime and by frequency band.

All splits use logged signals only. Residuals are normalised by the floors of the
`Problem` (1 = what sensor noise alone leaves), so shares compare like with like.

Regimes (per SYNC sample, first match wins), from set-points and measured motion:
    reversal      within 25 ms of a reversal of the nut (set-point or measured)
    load_change   with a load cell (`load_force_n`): within 50 ms of the measured load
                  changing faster than 5 kN/s (a load step or fast ramp; the diagnosis
                  maneuver's slow sine load stays below); without one: within 50 ms of a
                  step in the current demand that the set-point's acceleration does not
                  explain
    acceleration  |set-point or measured acceleration| above 10 % of its maximum
    cruise        moving (|v| above 2 % of its maximum) at steady speed
    dwell         at rest
Shares are of the excess energy above the floor (1 per normalised sample; white for the
bands), so a path or regime with nothing but noise gets a share near 0.
Frequency bands in multiples of the command fundamental f0: below (< 0.5 f0),
fundamental (0.5-1.5), harmonic_2 (1.5-2.5), harmonic_3 (2.5-3.5), harmonics_4_10
(3.5-10.5) and broadband (> 10.5 f0, up to Nyquist).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy.ndimage import maximum_filter1d, uniform_filter1d
from scipy.signal import get_window

from bench.gap import resim as R
from bench.gap.problem import Problem
from bench.signals import estimators as E

REGIMES = ("reversal", "load_change", "acceleration", "cruise", "dwell")
LOAD_RATE_N_PER_S = 5000.0   # load cell rate above which a sample is in a load change
BANDS = (("below_fundamental", 0.0, 0.5), ("fundamental", 0.5, 1.5),
         ("harmonic_2", 1.5, 2.5), ("harmonic_3", 2.5, 3.5),
         ("harmonics_4_10", 3.5, 10.5), ("broadband", 10.5, math.inf))
PATHS = ("drive", "mechanics", "screw", "sensors")
PATH_DOC = {
    "drive": "current demand -> current (logged demand replayed open loop, one period held)",
    "mechanics": "current -> motor speed (demand replayed in 50 ms segments, speed "
                 "re-synchronised to the encoder at each segment start)",
    "screw": "motor angle -> nut position (LVDT against encoder angle x ratio x lead/2pi "
             "through the nominal LVDT dynamics; backlash shows as lost motion at reversals)",
    "sensors": "encoder speed against the encoder angle's derivative through the nominal "
               "encoder dynamics (speed-sensor consistency)",
}


def _smooth(y: np.ndarray, w: int) -> np.ndarray:
    """Centred moving average over `w` samples, ends padded with the end values (scipy's
    "nearest"); a copy when `y` is shorter than `w`."""
    if w <= 1 or len(y) < w:
        return y.copy()
    return uniform_filter1d(np.asarray(y, float), w, mode="nearest")


def _dilate(mask: np.ndarray, half: int) -> np.ndarray:
    """`mask` widened by `half` samples on each side (a binary dilation)."""
    if half <= 0 or not mask.any():
        return mask.copy()
    return maximum_filter1d(mask, 2 * half + 1, mode="constant", cval=False)


def _change(y: np.ndarray, w: int) -> np.ndarray:
    """|change| of `y` (moving average over `w` samples) over the last `w` samples; 0 for
    the first `w`."""
    ys = _smooth(y, w)
    out = np.zeros(len(ys))
    if len(ys) > w:
        out[w:] = np.abs(ys[w:] - ys[:-w])
    return out


def regimes(p: Problem) -> np.ndarray:
    """Regime index (into REGIMES) of every sample."""
    d, dt, n = p.drive, p.dt, p.n
    travel = p.travel
    v_meas = _smooth(p.meas["motor_speed_rad_s"], 9) * travel           # nut m/s
    pos_mode = d.mode == 1
    v_sp = np.where(pos_mode, np.gradient(d.sp_pos, dt), d.sp_spd * travel)
    v_sp = np.where(d.mode == 0, 0.0, v_sp)
    # scales from the measured motion (a set-point step has an unbounded derivative)
    vmax = max(float(np.percentile(np.abs(v_meas), 99.5)), 1e-9)
    v_sp = np.clip(v_sp, -2 * vmax, 2 * vmax)
    v_thr = max(E.MOVING_FRACTION * vmax, 3.0 * p.noise_sigma.get("motor_speed_rad_s", 0.0) * travel / 3)
    a_meas = np.gradient(_smooth(v_meas, 9), dt)
    amax = max(float(np.percentile(np.abs(a_meas), 99.5)), 1e-12)
    accel = E.motion_regimes(a_meas, (0.1 * amax,)) > 0
    moving = (E.motion_direction(v_meas, v_thr) != 0) | (E.motion_direction(v_sp, v_thr) != 0)
    # reversals: sign changes of a velocity that is clearly non-zero on both sides
    rev = np.zeros(n, bool)
    half = max(1, int(round(0.025 / dt)))
    for v in (v_meas, v_sp):
        s = E.motion_direction(v, v_thr)
        idx = np.flatnonzero(s)
        if len(idx) > 1:
            flips = idx[1:][(s[idx[1:]] != s[idx[:-1]]) & (idx[1:] - idx[:-1] < int(0.3 / dt))]
            for k in flips:
                rev[max(0, k - half):k + half] = True
    # load changes: from the load cell when logged, else demand steps the set-point
    # acceleration does not explain
    load = np.zeros(n, bool)
    dem = d.demand
    w = max(1, int(round(0.01 / dt)))
    if d.load_n is not None:
        rate = _change(d.load_n, w) / (w * dt)
        load = _dilate(rate > LOAD_RATE_N_PER_S, int(round(0.05 / dt)))
    elif np.isfinite(dem).all():
        thr = max(0.5, 5.0 * p.noise_sigma.get("current_a", 0.1))
        ev = _change(dem, w) > thr
        ev &= ~_dilate(accel | rev, int(round(0.05 / dt)))
        load = _dilate(ev, int(round(0.05 / dt)))
    out = np.full(n, REGIMES.index("dwell"))
    out[moving] = REGIMES.index("cruise")
    out[accel] = REGIMES.index("acceleration")
    out[load] = REGIMES.index("load_change")
    out[rev] = REGIMES.index("reversal")
    return out


def command_fundamental(p: Problem, meta_hz: float | None = None) -> float:
    """The fundamental the bands are in multiples of (`estimators.fundamental_hz`): given
    (metadata or --fundamental), else the strongest line of the set-point velocity
    spectrum (nut velocity, position or speed mode), clipped to its 99th percentile."""
    f0 = E.fundamental_hz(meta_hz)
    if math.isfinite(f0):
        return f0
    d = p.drive
    # the set-point velocity: its lines are the oscillations, steps only add a flat floor
    sp = np.where(d.mode == 2, d.sp_spd * p.travel, np.gradient(d.sp_pos, p.dt))
    return E.fundamental_hz((), sp, p.dt, clip_percentile=99)


def band_shares(r: np.ndarray, dt: float, f0: float) -> dict[str, float]:
    """Share of the residual's excess energy (above a white floor of 1 per sample) in
    each band; sums to 1, or all 0 when nothing exceeds the floor."""
    if not (math.isfinite(f0) and f0 > 0) or len(r) < 8:
        return {b[0]: float("nan") for b in BANDS}
    w = get_window("hann", len(r), fftbins=False)       # symmetric Hann
    spec = np.abs(np.fft.rfft(r * w)) ** 2
    tot = float(spec.sum())
    if tot <= 0:
        return {b[0]: 0.0 for b in BANDS}
    spec *= float(np.sum(r * r)) / tot              # bins sum to the residual energy
    floor = len(r) / len(spec)                      # white noise of unit variance, per bin
    f = np.fft.rfftfreq(len(r), dt) / f0
    ex = {}
    for name, lo, hi in BANDS:
        m = (f >= lo) & (f < hi)
        ex[name] = max(float(spec[m].sum()) - floor * int(m.sum()), 0.0)
    s = sum(ex.values())
    return {k: (v / s if s > 0 else 0.0) for k, v in ex.items()}


def regime_shares(r2: np.ndarray, reg: np.ndarray) -> dict[str, dict[str, float]]:
    """Per regime: share of the excess residual energy (above the floor of 1 per sample),
    share of time and mean normalised energy (1 = noise floor)."""
    ex = {}
    out = {}
    for i, name in enumerate(REGIMES):
        m = reg == i
        ex[name] = max(float(r2[m].sum()) - float(m.sum()), 0.0)
        out[name] = {"time_share": float(m.mean()),
                     "mean_energy": float(r2[m].mean()) if m.any() else float("nan")}
    tot = sum(ex.values())
    for name in REGIMES:
        out[name]["energy_share"] = ex[name] / tot if tot > 0 else 0.0
    return out


def path_residuals(p: Problem, cols: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Residuals (signal units) of each path computed on logged-style `cols`."""
    base, dt = p.base, p.dt
    out: dict[str, np.ndarray] = {}
    ang, pos, spd = cols["motor_angle_rad"], cols["position_m"], cols["motor_speed_rad_s"]
    dem = cols.get("current_demand_a")
    if dem is not None and np.isfinite(dem).all():
        drv = R.Drive(p.drive.t, p.drive.sp_pos, p.drive.sp_spd, p.drive.mode, dem,
                      p.drive.x0_m, p.drive.x0_true_m, p.drive.load_n)
        ol = R.open_loop(base, drv)
        out["drive"] = cols["current_a"] - ol["current_a"]
        mech = R.mechanics_replay(base, drv, _smooth(spd, 3))
        out["mechanics"] = spd - mech["motor_speed_rad_s"]
    x0 = p.drive.x0_true_m if p.drive.x0_true_m is not None else p.drive.x0_m
    if p.drive.x0_true_m is not None:
        kin = R.lvdt_dynamics(ang * p.travel, dt, base)
    else:
        kin = R.screw_kinematics(ang, x0, base, dt)
    out["screw"] = pos - kin
    out["sensors"] = spd - R.encoder_speed_from_angle(ang, base, dt)
    return out


def lost_motion(p: Problem, screw_residual: np.ndarray) -> float:
    """Lost motion of the screw path (m): median LVDT-minus-kinematics residual while the
    screw pushes the nut backwards minus while it pushes it forwards: the axial lost
    motion, which is the plant's backlash (along the contact normal, eq. 5.19-5.24) /
    (cos alpha sin beta), or the compliance times the contact force.

    The side the screw pushes is that of F_ext + F_s sign(v) (nut equilibrium, eq. 5.31,
    F_s the nominal nut friction): the direction of motion on an unloaded run, the load's
    sign under a load well above friction (then reversals do not cross the backlash, load
    sign changes do). Samples where that force is within F_s / 2 of zero are left out."""
    v = _smooth(p.meas["motor_speed_rad_s"], 9)
    thr = max(0.05 * float(np.percentile(np.abs(v), 99)), 1e-9)
    sv = np.where(v > thr, 1.0, np.where(v < -thr, -1.0, 0.0))
    fc = p.base.screw.nut_static_friction_n
    load = np.zeros_like(v) if p.drive.load_n is None else _smooth(
        np.nan_to_num(p.drive.load_n), 9)
    push = load + fc * sv
    margin = np.where(sv != 0.0, 0.5 * fc, 1.5 * fc)
    fwd, back = push > margin, push < -margin
    if fwd.sum() < 10 or back.sum() < 10:
        return float("nan")
    return float(np.median(screw_residual[back]) - np.median(screw_residual[fwd]))


PATH_UNITS = {"drive": "A", "mechanics": "rad/s", "screw": "m", "sensors": "rad/s"}


def localise(p: Problem, nominal: dict[str, np.ndarray], log_cols: dict[str, np.ndarray],
             floor_cols: list[dict[str, np.ndarray]], clean_cols: dict[str, np.ndarray],
             f0: float) -> dict[str, Any]:
    """The localisation block of the JSON: signals, paths, regimes, bands.

    `log_cols`: the logged columns; `clean_cols`: the nominal closed-loop re-simulation's
    columns (noise-free); `floor_cols`: noisy nominal re-simulations (the path floors).
    """
    n = p.n
    reg = regimes(p)
    sig: dict[str, Any] = {}
    tot_excess = 0.0
    excess = {}
    for s in R.SIGNALS:
        r = (p.meas[s] - nominal[s]) / p.sigma[s]
        r2 = r ** 2
        e = float(r2.mean())
        excess[s] = max(e - 1.0, 0.0)
        tot_excess += excess[s]
        sig[s] = {"rms": float(np.sqrt(np.mean((p.meas[s] - nominal[s]) ** 2))),
                  "floor": p.sigma[s], "energy": e,
                  "by_regime": regime_shares(r2, reg),
                  "by_band": band_shares(r, p.dt, f0)}
    for s in R.SIGNALS:
        sig[s]["share"] = excess[s] / tot_excess if tot_excess > 0 else 0.0
    # paths -----------------------------------------------------------------------------
    paths: dict[str, Any] = {}
    pr = path_residuals(p, log_cols)
    pr_clean = path_residuals(p, clean_cols)
    pr_floor = [path_residuals(p, fc) for fc in floor_cols]
    p_excess = {}
    for name in PATHS:
        if name not in pr:
            paths[name] = {"available": False,
                           "why": "the log has no current_demand_a (ECU demand)"}
            continue
        r = pr[name]
        floor2 = float(np.mean([np.mean(f[name] ** 2) for f in pr_floor])) if pr_floor \
            else float(np.mean(pr_clean[name] ** 2))
        floor = math.sqrt(max(floor2, 1e-30))
        rn = r / floor
        e = float(np.mean(rn ** 2))
        p_excess[name] = max(e - 1.0, 0.0)
        paths[name] = {"available": True, "doc": PATH_DOC[name], "unit": PATH_UNITS[name],
                       "rms": float(np.sqrt(np.mean(r ** 2))), "floor": floor, "energy": e,
                       "by_regime": regime_shares(rn ** 2, reg),
                       "by_band": band_shares(rn, p.dt, f0)}
    if "screw" in pr:
        paths["screw"]["lost_motion_m"] = lost_motion(p, pr["screw"])
    tot = sum(p_excess.values())
    for name in p_excess:
        paths[name]["share"] = p_excess[name] / tot if tot > 0 else 0.0
    counts = {name: float(np.mean(reg == i)) for i, name in enumerate(REGIMES)}
    return {"signals": sig, "paths": paths, "regime_time_share": counts,
            "fundamental_hz": f0, "samples": n, "sample_period_s": p.dt,
            "_regimes": reg, "_path_residuals": pr}
