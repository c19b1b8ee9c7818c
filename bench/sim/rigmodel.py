"""The generic actuator model for logs the bench did not simulate.

Any rig, at the nut: an equivalent mass m, a force per ampere k_f, Coulomb friction F_c,
viscous friction c, the logged load F_ext (x the description's load sign):

    m dv/dt = k_f i - F_c sgn(v) - c v + F_ext,   dx/dt = v

Coulomb friction is integrated implicitly (the nut sticks when the friction can stop it
within one step), so the step need not resolve a friction regularisation.

Two ways to drive it, both run at the model's own step (at most `H_MAX`, and a whole
fraction of the controller's sample time) and sampled at the log's own instants:

- `closed_loop`: a generic cascade, every sample time T_s: speed demand
  v* = K_p (x_sp - x) + ff dx_sp/dt; current demand i* = K_v (v* - v) + K_i int(v* - v),
  saturated at +-i_max (the integral held while saturated); a first-order current loop
  (time constant tau_i, 0: ideal). The set-point between two log samples is the straight
  line between them (it is a command, known at the log's instants only).
- `current_driven`: the measured current (linear between samples) drives the mechanics
  instead of a controller, in segments re-started from the measured position and speed
  (a line fitted over +-20 ms; a long open-loop integration would drift).

A position-locked resistance (`EXTRA`: a spall the balls roll over) adds
F_b exp(-(x - x_b)^2 / 2 w^2) to the Coulomb friction; it is zero in a healthy model.

The logged current is i + i_0 for a drive with a current loop; for a stepper with a
chopper drive the logged current is taken as i_0 + |i| (the drive's sensor sees an
amplitude). That is all this family says about a stepper: the load angle enters only in
its small-angle, linear form (a stiffness and a damping: the cascade's K_v K_p k_f and
K_v k_f), the chopper's current regulation, idle current reduction, step and microstep
ripple and resonance not at all.
"""

from __future__ import annotations

import math

import numpy as np

from plant_rt.jit import njit

THETA = ("mass_kg", "force_per_a_n", "coulomb_n", "viscous_n_s_per_m", "current_offset_a",
         "kp_1_s", "kv_a_s_per_m", "ki_a_per_m", "feedforward", "current_limit_a",
         "current_tau_s", "bump_n", "bump_at_m", "bump_width_m")
"""The model's values, in this order in the vectors the compiled functions take."""
M, KF, FC, C, I0, KP, KV, KI, FF, IMAX, TAU, BA, BX, BW = range(len(THETA))
EXTRA = {"bump_n": 0.0, "bump_at_m": 0.0, "bump_width_m": 2e-3}
"""Values no description gives: a position-locked force (N) opposing motion around one
nut position (m) with a Gaussian width (m), zero in a healthy model (`bench.rig.riggap`)."""
H_MAX = 2e-4            # s: the model's largest step


@njit(cache=True)
def _mech(x, v, f_drive, m, fc, c, h):  # pragma: no cover - compiled
    """One step of the mechanics with implicit Coulomb and viscous friction."""
    den = 1.0 + h * c / m
    vt = (v + h * f_drive / m) / den
    dv = h * fc / m / den
    if abs(vt) <= dv:
        v = 0.0
    elif vt > 0.0:
        v = vt - dv
    else:
        v = vt + dv
    return x + h * v, v


@njit(cache=True)
def _closed(th, stepper, t, sp, fext, ts, h, x0):  # pragma: no cover - compiled
    """`closed_loop`'s compiled core: (position, logged current) at the instants `t`."""
    n = len(t)
    xo = np.full(n, np.nan)
    io = np.full(n, np.nan)
    x, v, i, integ, icmd = x0, 0.0, 0.0, 0.0, 0.0
    a = math.exp(-h / th[TAU]) if th[TAU] > 0.0 else 0.0
    nsub = max(1, int(round(ts / h)))
    k, step, seg = 0, 0, 0
    tt = t[0]
    while k < n:
        while k < n and tt >= t[k] - 1e-9:
            xo[k] = x
            io[k] = th[I0] + (abs(i) if stepper else i)
            k += 1
        if k >= n:
            break
        if step % nsub == 0:
            while seg < n - 2 and tt >= t[seg + 1]:
                seg += 1
            dts = t[seg + 1] - t[seg]
            vsp = (sp[seg + 1] - sp[seg]) / dts
            xsp = sp[seg] + vsp * (tt - t[seg])
            ev = th[KP] * (xsp - x) + th[FF] * vsp - v
            ni = integ + th[KI] * ev * ts
            icmd = th[KV] * ev + ni
            lim = th[IMAX]
            if icmd > lim:
                icmd = lim
            elif icmd < -lim:
                icmd = -lim
            else:
                integ = ni
        i = a * i + (1.0 - a) * icmd
        f = th[KF] * i + fext[max(k - 1, 0)]
        fc = th[FC]
        if th[BA] != 0.0:
            fc += th[BA] * math.exp(-0.5 * ((x - th[BX]) / th[BW]) ** 2)
        x, v = _mech(x, v, f, th[M], fc, th[C], h)
        if not math.isfinite(x) or abs(x) > 1e3:
            break
        step += 1
        tt = t[0] + step * h
    return xo, io


@njit(cache=True)
def _driven(th, t, cur, x0, v0, fext, seg, h):  # pragma: no cover - compiled
    """`current_driven`'s compiled core: the position at the instants `t`."""
    n = len(t)
    xo = np.full(n, np.nan)
    for k0 in range(0, n - 1, seg):
        k1 = min(k0 + seg, n - 1)
        x = x0[k0]
        v = v0[k0]
        xo[k0] = x
        for k in range(k0, k1):
            nsub = max(1, int(math.ceil((t[k + 1] - t[k]) / h)))
            hh = (t[k + 1] - t[k]) / nsub
            for j in range(nsub):
                w = (j + 0.5) / nsub
                ik = (1.0 - w) * cur[k] + w * cur[k + 1]
                f = th[KF] * (ik - th[I0]) + fext[k]
                x, v = _mech(x, v, f, th[M], th[FC], th[C], hh)
            xo[k + 1] = x
    return xo


def model_step(sample_period_s: float) -> float:
    """The model's step: the controller's sample time divided into steps of <= H_MAX."""
    return sample_period_s / max(1, math.ceil(sample_period_s / H_MAX - 1e-9))


def closed_loop(theta: np.ndarray, stepper: bool, t: np.ndarray, setpoint: np.ndarray,
                load_n: np.ndarray, sample_period_s: float, x0: float
                ) -> tuple[np.ndarray, np.ndarray]:
    """(position m, logged current A) the cascade model gives at the instants `t`
    (module doc); NaN after a diverging state."""
    h = model_step(sample_period_s)
    return _closed(np.asarray(theta, float), bool(stepper), np.asarray(t, float),
                   np.asarray(setpoint, float), np.nan_to_num(np.asarray(load_n, float)),
                   float(sample_period_s), h, float(x0))


def current_driven(theta: np.ndarray, t: np.ndarray, current: np.ndarray,
                   position: np.ndarray, load_n: np.ndarray, segment_s: float = 0.5
                   ) -> np.ndarray:
    """The position (m) the mechanics give at the instants `t` when the measured current
    drives them, re-started every `segment_s` from the measured position and speed
    (`restart_state`) (module doc)."""
    t = np.asarray(t, float)
    dt = float(np.median(np.diff(t)))
    seg = max(2, round(segment_s / dt))
    x0, v0 = np.zeros(len(t)), np.zeros(len(t))
    starts = np.arange(0, len(t), seg)
    x0[starts], v0[starts] = restart_state(t, np.asarray(position, float),
                                           max(1, round(0.02 / dt)), starts)
    return _driven(np.asarray(theta, float), t, np.nan_to_num(np.asarray(current, float)),
                   x0, v0, np.nan_to_num(np.asarray(load_n, float)), seg, H_MAX)


def restart_state(t: np.ndarray, x: np.ndarray, half: int, at: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Position and speed at the samples `at`, each from a straight line fitted over the
    samples within +-`half` of it (a central fit: exact on a parabola's slope, and it
    averages the noise that a two-point difference would multiply)."""
    n = len(t)
    xs, vs = np.empty(len(at)), np.empty(len(at))
    for j, k in enumerate(at):
        a, b = max(0, k - half), min(n, k + half + 1)
        tt, yy = t[a:b] - t[k], x[a:b]
        ok = np.isfinite(yy)
        if ok.sum() < 2:
            xs[j], vs[j] = x[k], 0.0
            continue
        v, c = np.polyfit(tt[ok], yy[ok], 1)
        xs[j], vs[j] = c, v
    return xs, vs
