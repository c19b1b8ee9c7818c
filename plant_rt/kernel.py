"""The compiled fixed-step core of the EMA plant (thesis chapter 5).

`advance(x, p, u, out)` integrates the state vector `x` over one SYNC period with
fixed sub-steps, holding the inputs `u`, and writes period diagnostics into `out`.
Everything is plain float64 arrays so numba compiles one specialisation, cached on disk.

Layout of `x`, `p`, `u` and `out` is given by the index constants below; `plant_rt.model`
builds `p` from a `PlantParams` and names the states for users. What changes during a
run (current demand, preload, backlash, friction scale, held noise) is input, not a
parameter; the external force profile is evaluated per sub-step from `p`.

Sign conventions: x (nut position), Omega (screw angle) and z (contact normal) grow in
the direction a positive motor current drives the nut. F_ext > 0 opposes positive motion
(eq. 5.30).
"""

from __future__ import annotations

import math

import numpy as np

from plant_rt.contacts import HERTZ_MIN_PRELOAD_FRAC, hertz_share, worn_nut
from plant_rt.jit import njit
from plant_rt.pi import clamped_pi
from plant_rt.wear import effects_from_depth

# the wear mapping of `plant_rt.wear`, compiled here (plant_rt.wear itself stays numba-free)
_effects_from_depth = njit(cache=True, inline="always", error_model="numpy",
                           fastmath={"nnan", "ninf", "nsz"})(effects_from_depth)
# the Hertzian preload law of `plant_rt.contacts`, compiled here (contacts stays numba-free)
_hertz_share = njit(cache=True, inline="always", error_model="numpy",
                    fastmath={"nnan", "ninf", "nsz"})(hertz_share)
# a double nut preloaded by an interference that wear eats (`plant_rt.contacts.worn_nut`)
_worn_nut = njit(cache=True, inline="always", error_model="numpy",
                 fastmath={"nnan", "ninf", "nsz"})(worn_nut)


@njit(cache=True, error_model="numpy", fastmath={"nnan", "ninf", "nsz"})
def _hertz_ratio(f_axial: float, preload_n: float, ref_n: float) -> float:
    """`plant_rt.contacts.hertz_stiffness_ratio`, compiled (same arithmetic; tested equal)."""
    fpr = max(preload_n, HERTZ_MIN_PRELOAD_FRAC * ref_n)
    f = abs(f_axial)
    if f < 1e-6 * ref_n:
        return (fpr / ref_n) ** (1.0 / 3.0)
    return (ref_n / fpr) ** (2.0 / 3.0) * _hertz_share(f / ref_n) / _hertz_share(f / fpr)

# --- state vector x -------------------------------------------------------------------
(I, CI, IM, TQ, TEMP, TH, OM, X1, V1, X2, V2, ZB1, VB1, ZB2, VB2,
 LY, LYD, EY, EYD, STS, STN1, STN2, T,
 E_IN, E_R, E_FRS, E_FRN, E_EXT, E_EMF, E_MIS, E_ETA, E_PR, E_CLAMP, E_MOT, E_DAMP,
 WEAR_V) = range(36)
NHIST = 16
"""Screw angles of the last NHIST SYNCs kept for a count-difference speed estimator
(`sensors.encoder_speed_window` <= NHIST): x[TH_HIST + j] is the screw angle at the SYNC
j + 1 periods before the state's time."""
TH_HIST = 36
NX = TH_HIST + NHIST
STATE_NAMES = (
    "current_a", "current_pi_integrator_v", "current_sensor_a", "motor_torque_nm",
    "temperature_k", "screw_angle_rad", "screw_speed_rad_s", "nut1_position_m",
    "nut1_speed_m_s", "nut2_position_m", "nut2_speed_m_s", "ball1_z_m", "ball1_speed_m_s",
    "ball2_z_m", "ball2_speed_m_s", "lvdt_y_m", "lvdt_ydot_m_s", "encoder_y_rad_s",
    "encoder_ydot_rad_s2", "screw_stuck", "nut1_stuck", "nut2_stuck", "t_s",
    "e_electrical_in_j", "e_joule_j", "e_screw_friction_j", "e_nut_friction_j",
    "e_external_j", "e_back_emf_j", "e_lever_mismatch_j", "e_reducer_loss_j",
    "e_preload_j", "e_current_clamp_j", "e_motor_torque_j", "e_contact_damping_j",
    "wear_volume_m3") + tuple(f"screw_angle_{j + 1}_syncs_ago_rad" for j in range(NHIST))
# WEAR_V: worn volume of the ball tracks (m^3, Archard; `plant_rt.wear`), accumulated per
# sub-step when p[P_WEAR_GAIN] != 0

# --- parameter vector p ---------------------------------------------------------------
(P_R, P_L, P_KE, P_KT, P_IMAX, P_VDC, P_RTH, P_TAMB, P_TAUW, P_TAUH, P_ALPHA_R,
 P_JEQ, P_TAU, P_ETA, P_CS, P_STRA, P_STRV, P_CVISC, P_Z, P_LEAD, P_G, P_LEVER_V,
 P_LEVER_R, P_FV, P_FS, P_CN, P_MN, P_MB, P_KSTAR, P_MSLOPE, P_CDAMP,
 P_LZETA, P_LSIG, P_EZETA, P_ESIG, P_TAUC, P_KPI, P_KII, P_FPWM, P_PWM_SW, P_BALL_DYN,
 P_DT, P_NBALL, P_NSUB, P_LOAD_KIND, P_LOAD_AMP, P_LOAD_T0, P_LOAD_RATE, P_LOAD_FREQ,
 P_TRAVEL, P_AERO_GAIN, P_WEAR_ON, P_WEAR_GAIN, P_WEAR_AREA, P_WEAR_FRIC, P_LTAU,
 P_HREF, P_PDRAG, P_INTERF) = range(59)
NP = 59
# P_LTAU: the LVDT's first-order time constant (s); 0: the second-order filter of eq. 5.1
# P_HREF: the Hertzian preload law's reference preload F_ref (N); 0: eq. 5.21's linear law
# P_PDRAG: the preloaded nut's drag torque at the screw per N of preload (N m/N), added to
# C_s of eq. 5.14; 0: none beyond the rolling terms of eq. 5.13 and 5.31
# P_INTERF: 1 = the preload is held by an interference that the backlash (a wear clearance)
# eats first (screw.preload_by_interference); 0: eq. 5.29's preload force
# load kinds (P_LOAD_KIND): the order of `LoadParams.kind`'s choices
LOAD_KINDS = ("none", "step", "ramp", "sine", "aero")

# --- inputs u (held over one SYNC period) -----------------------------------------------
(U_IDEM, U_PRELOAD, U_BACKLASH, U_FSCALE, U_VSCALE, U_INOISE, U_IGAIN, U_IOFF, U_FEXT,
 U_GUST, U_ISEP) = range(11)
NU = 11
# U_IGAIN, U_IOFF, U_INOISE: the current sensor's gain, offset and noise sample, which the
# drive's current loop sees (eq. 5.2). U_ISEP: 1 = the logged current is a separate
# channel (sensors.current_in_loop false): the drive regulates the true current and the
# sensor's errors are in the log alone; 0 (the thesis' drive) = they enter the loop
# U_PRELOAD, U_BACKLASH, U_FSCALE: the degradation of the period; under Archard wear
# (p[P_WEAR_ON]) those of the new actuator, to which the wear of WEAR_V is added.
# U_GUST: the aero load's gust force over the period (N; used only by load kind aero)
# U_FEXT: external axial force (N) added to the load profile of p over the period: a
# logged load-cell force replayed by the gap diagnosis, or a disturbance injected in-process

# --- period diagnostics out -------------------------------------------------------------
(O_FRIC_T, O_FRIC_F, O_REACT_T, O_VOLT, O_FEXT, O_ILIM, O_PMAX1, O_PMAX2,
 O_PRELOAD, O_BACKLASH, O_FSCALE) = range(11)
NO = 11
DIAG_NAMES = ("friction_torque_nm", "friction_force_n", "reaction_torque_nm", "voltage_v",
              "ext_force_n", "current_limited", "contact_force1_max_n", "contact_force2_max_n",
              "preload_n", "backlash_m", "friction_scale")

TWO_PI = 2.0 * math.pi
# Only the fast-math flags that cannot change the rounding of finite values: the same
# step must give bit-identical results called alone (live node) or inlined in the
# compiled closed loop (harness), or a stiction decision can flip one sub-step apart.
FM = {"nnan", "ninf", "nsz"}


@njit(cache=True, inline="always", error_model="numpy", fastmath=FM)
def _sign(v: float) -> float:
    return 1.0 if v > 0.0 else (-1.0 if v < 0.0 else 0.0)


@njit(cache=True, inline="always", error_model="numpy", fastmath=FM)
def contact(d: float, dd: float, k: float, c: float, half_band: float) -> tuple[float, float]:
    """Contact force of one spring-damper with a dead zone (eq. 5.17-5.24): (F, F_damping).

    d: relative approach along z (m), dd its rate; half_band: b_max/4 for one contact
    (eq. 5.19-5.20), so the dead zone |d| <= half_band gives zero force (eq. 5.23-5.24).
    The damping force is limited to |c dd| <= |k delta| (eq. 5.22: the force-continuity
    function f of eq. 5.17-5.18), so the force never changes sign through damping.
    """
    if d > half_band:
        delta = d - half_band
    elif d < -half_band:
        delta = d + half_band
    else:
        return 0.0, 0.0
    fs = k * delta
    fd = c * dd
    if fs > 0.0:
        if fd > fs:
            fd = fs
        elif fd < -fs:
            fd = -fs
    else:
        if fd > -fs:
            fd = -fs
        elif fd < fs:
            fd = fs
    return fs + fd, fd


@njit(cache=True, inline="always", error_model="numpy", fastmath=FM)
def contact_force(d: float, dd: float, k: float, c: float, half_band: float) -> float:
    """The force of `contact` alone."""
    return contact(d, dd, k, c, half_band)[0]


@njit(cache=True, inline="always", error_model="numpy", fastmath=FM)
def _on_time(t: float, a: float, period: float) -> float:
    """Integral from 0 to t of [carrier(s) < a] for a 0..1..0 triangular carrier (sec. 5.3)."""
    n = math.floor(t / period)
    ph = t - n * period
    on = n * a * period + min(ph, 0.5 * a * period)
    th = period * (1.0 - 0.5 * a)
    if ph > th:
        on += ph - th
    return on


@njit(cache=True, inline="always", error_model="numpy", fastmath=FM)
def _ext_force(p: np.ndarray, t: float, xn: float, gust: float) -> float:
    """F_ext of the load profile at time t (eq. 5.29-5.30); xn: nut position, gust: the
    period's gust force (aero only)."""
    kind = p[P_LOAD_KIND]
    if kind == 0.0:
        return 0.0
    if kind == 4.0:  # aero: hinge moment grows with deflection, restoring (docs/model.md)
        return p[P_AERO_GAIN] * xn + gust
    t0 = p[P_LOAD_T0]
    if t < t0:
        return 0.0
    amp = p[P_LOAD_AMP]
    if kind == 3.0:  # sine
        return amp * math.sin(TWO_PI * p[P_LOAD_FREQ] * (t - t0))
    rate = p[P_LOAD_RATE] if kind == 2.0 else abs(amp) / 0.01  # step: 0.01 s rise (5.7.3)
    ramp = rate * (t - t0)
    if ramp >= abs(amp):
        return amp
    return ramp if amp > 0.0 else -ramp


@njit(cache=True, error_model="numpy", fastmath=FM)
# noqa: C901 below: the compiled inner loop; helpers per branch cost speed in numba
def advance(x: np.ndarray, p: np.ndarray, u: np.ndarray, out: np.ndarray) -> None:  # noqa: C901
    """Integrate one SYNC period (p[P_NSUB] sub-steps of p[P_DT]) holding inputs u."""
    # long: one sub-step of every coupled block (drive to sensors) on shared locals, in order
    dt = p[P_DT]
    nsub = int(p[P_NSUB])
    R0, L, KE, KT = p[P_R], p[P_L], p[P_KE], p[P_KT]
    IMAX, VDC = p[P_IMAX], p[P_VDC]
    tau, eta, jeq = p[P_TAU], p[P_ETA], p[P_JEQ]
    fpr, backlash, fscale = u[U_PRELOAD], u[U_BACKLASH], u[U_FSCALE]
    if p[P_INTERF] != 0.0:      # the clearance eats the preload interference first
        fpr, backlash = _worn_nut(fpr, backlash, p[P_KSTAR], p[P_MSLOPE], p[P_Z], p[P_G],
                                  p[P_HREF])
    if p[P_WEAR_ON] != 0.0:     # Archard wear: effects of the worn volume (plant_rt.wear)
        w_loss, w_back, w_fric = _effects_from_depth(
            x[WEAR_V] / p[P_WEAR_AREA], fpr, p[P_KSTAR], p[P_MSLOPE], p[P_Z], p[P_G],
            p[P_WEAR_FRIC])
        fpr = fpr - w_loss
        backlash = backlash + w_back
        fscale = fscale * w_fric
    vscale = u[U_VSCALE]
    wgain = p[P_WEAR_GAIN]
    wearing = wgain != 0.0
    gust = u[U_GUST]
    CS = (p[P_CS] + p[P_PDRAG] * fpr) * fscale     # eq. 5.14 (+ the preload's drag)
    STRA, STRV = p[P_STRA], p[P_STRV]
    CVISC = p[P_CVISC] * vscale
    Z, lead, g = p[P_Z], p[P_LEAD], p[P_G]
    lever_v, lever_r, fv = p[P_LEVER_V], p[P_LEVER_R], p[P_FV]
    FS = p[P_FS] * fscale
    CN = p[P_CN] * vscale
    mhalf = 0.5 * p[P_MN]
    mb = p[P_MB]
    k = p[P_KSTAR] + p[P_MSLOPE] * fpr          # eq. 5.21
    href = p[P_HREF]
    hertz = href > 0.0      # Hertzian nut: k of eq. 5.21 at F_ref, scaled per sub-step
    k_ref = p[P_KSTAR] + p[P_MSLOPE] * href
    f_k = 0.0               # the load the Hertzian k was last computed at (held over a
    have_k = False          # period when the load is the replayed U_FEXT alone)
    c = p[P_CDAMP]
    hb = 0.25 * backlash                         # b_max/4 per contact (eq. 5.19-5.20)
    kin = lead / TWO_PI * g                      # dz_s/dOmega (eq. 5.26)
    lever_kin = lead / TWO_PI * g                # work-consistent lever of C_V
    a_c = 1.0 - math.exp(-dt / p[P_TAUC])
    a_h = 1.0 - math.exp(-dt / p[P_TAUH])
    a_w = 1.0 - math.exp(-dt / p[P_TAUW])
    kpi, kii = p[P_KPI], p[P_KII]
    period = 1.0 / p[P_FPWM]
    switching = p[P_PWM_SW] != 0.0
    dynamic = p[P_BALL_DYN] != 0.0
    nball = int(p[P_NBALL])
    dtb = dt / nball
    dtb_mb = dtb / mb            # no division in the ball micro-step loop
    lz, ls = p[P_LZETA], p[P_LSIG]
    lvdt_first = p[P_LTAU] > 0.0
    a_l = 1.0 - math.exp(-dt / p[P_LTAU]) if lvdt_first else 0.0
    ez, es = p[P_EZETA], p[P_ESIG]
    idem = u[U_IDEM]
    if u[U_ISEP] == 0.0:        # the drive's feedback is the logged current sensor
        igain, ioff, inoise = u[U_IGAIN], u[U_IOFF], u[U_INOISE]
    else:                       # a separate logging channel: the drive sees the true current
        igain, ioff, inoise = 1.0, 0.0, 0.0
    alpha_r, tamb, rth = p[P_ALPHA_R], p[P_TAMB], p[P_RTH]
    ilim = 0.0
    if idem >= IMAX:            # the drive limits the demand to i_max (table 5.2)
        idem = IMAX
        ilim = 1.0
    elif idem <= -IMAX:
        idem = -IMAX
        ilim = 1.0

    acc_cf = 0.0
    acc_ff = 0.0
    acc_cv = 0.0
    acc_v = 0.0
    acc_fe = 0.0
    pmax1 = 0.0
    pmax2 = 0.0
    acc_w = 0.0
    # the angle at this SYNC joins the count-difference estimator's history (I/O only)
    for j in range(NHIST - 1, 0, -1):
        x[TH_HIST + j] = x[TH_HIST + j - 1]
    x[TH_HIST] = x[TH]

    for _ in range(nsub):
        t = x[T]
        i = x[I]
        om = x[OM]
        w_m = om / tau                             # motor speed (eq. 5.8)
        # ---- drive: current PI with clamping anti-windup, measured current ----------
        i_fb = igain * x[IM] + ioff + inoise
        vset, x[CI] = clamped_pi(idem - i_fb, x[CI], kpi, kii, dt, VDC)
        # ---- PWM and inverter (section 5.3) --------------------------------------------
        if switching:
            m = vset / VDC
            am = abs(m)
            duty = (_on_time(t + dt, am, period) - _on_time(t, am, period)) / dt
            va = _sign(m) * VDC * duty
        else:
            va = vset
        # ---- motor (eq. 5.3-5.6): Crank-Nicolson, so the energy books close exactly -----
        rt = R0 * (1.0 + alpha_r * (x[TEMP] - tamb))
        hr = 0.5 * dt * rt / L
        i_new = (i * (1.0 - hr) + dt * (va - KE * w_m) / L) / (1.0 + hr)
        i_avg = 0.5 * (i + i_new)
        x[E_IN] += va * i_avg * dt
        x[E_R] += rt * i_avg * i_avg * dt
        x[E_EMF] += KE * w_m * i_avg * dt
        if i_new > IMAX:                        # current limit of the motor (sec. 5.4)
            x[E_CLAMP] += 0.5 * L * (i_new * i_new - IMAX * IMAX)
            i_new = IMAX
            ilim = 1.0
        elif i_new < -IMAX:
            x[E_CLAMP] += 0.5 * L * (i_new * i_new - IMAX * IMAX)
            i_new = -IMAX
            ilim = 1.0
        x[I] = i_new
        x[IM] += (i_new - x[IM]) * a_c                                   # eq. 5.2
        x[TQ] += (KT * i_new - x[TQ]) * a_h                              # eq. 5.4 + demod
        x[TEMP] += (tamb + rt * i_new * i_new * rth - x[TEMP]) * a_w  # eq. 5.5
        fext = _ext_force(p, t, 0.5 * (x[X1] + x[X2]), gust) + u[U_FEXT]  # F_ext, eq. 5.29
        if hertz and not (have_k and fext == f_k):   # the double nut's secant stiffness
            k = k_ref * _hertz_ratio(fext, fpr, href)   # at this load and preload
            f_k = fext
            have_k = True
        # ---- ball contacts (eq. 5.16-5.24) ---------------------------------------------
        zs = kin * x[TH]
        vzs = kin * om
        zn1 = g * x[X1]
        zn2 = g * x[X2]
        vzn1 = g * x[V1]
        vzn2 = g * x[V2]
        if dynamic:
            ps1 = 0.0
            pn1 = 0.0
            ps2 = 0.0
            pn2 = 0.0
            edamp = 0.0
            # ball states in locals for the micro-step loop (same arithmetic, registers)
            vb1, vb2, zb1, zb2 = x[VB1], x[VB2], x[ZB1], x[ZB2]
            for kb in range(nball):
                tb = kb * dtb
                zs_b = zs + vzs * tb
                d1 = vb1 - vzs
                d2 = vzn1 - vb1
                d3 = vb2 - vzs
                d4 = vzn2 - vb2
                f1, fd1 = contact(zb1 - zs_b, d1, k, c, hb)
                f2, fd2 = contact(zn1 + vzn1 * tb - zb1, d2, k, c, hb)
                f3, fd3 = contact(zb2 - zs_b, d3, k, c, hb)
                f4, fd4 = contact(zn2 + vzn2 * tb - zb2, d4, k, c, hb)
                # P'_j = -f (eq. 5.17), P_j = f (eq. 5.18); ball: M_b z'' = P' + P (5.16)
                vb1 += (f2 - f1) * dtb_mb
                vb2 += (f4 - f3) * dtb_mb
                zb1 += dtb * vb1
                zb2 += dtb * vb2
                ps1 -= f1
                pn1 += f2
                ps2 -= f3
                pn2 += f4
                edamp += fd1 * d1 + fd2 * d2 + fd3 * d3 + fd4 * d4
            x[VB1], x[VB2], x[ZB1], x[ZB2] = vb1, vb2, zb1, zb2
            ps1 /= nball
            pn1 /= nball
            ps2 /= nball
            pn2 /= nball
            x[E_DAMP] += Z * edamp * dtb
        else:
            # massless balls: the two contacts in series, k/2, c/2, dead zone b/2
            pn1, fd1 = contact(zn1 - zs, vzn1 - vzs, 0.5 * k, 0.5 * c, 2.0 * hb)
            pn2, fd2 = contact(zn2 - zs, vzn2 - vzs, 0.5 * k, 0.5 * c, 2.0 * hb)
            ps1 = -pn1
            ps2 = -pn2
            x[ZB1] = 0.5 * (zn1 + zs)
            x[ZB2] = 0.5 * (zn2 + zs)
            x[E_DAMP] += Z * (fd1 * (vzn1 - vzs) + fd2 * (vzn2 - vzs)) * dt
        if abs(pn1) > pmax1:
            pmax1 = abs(pn1)
        if abs(pn2) > pmax2:
            pmax2 = abs(pn2)
        # ---- screw shaft (eq. 5.9-5.15) with the stiction logic of fig. 5.17 ------------
        cm = eta * x[TQ] / tau                                          # eq. 5.7
        cv = Z * (ps1 + ps2) * lever_v                                  # eq. 5.10, 5.15
        roll = Z * fv * (abs(ps1) + abs(ps2)) * lever_r                 # eq. 5.13, 3rd term
        c_stat = CS * (1.0 + STRA) + roll
        tt = cm - cv
        if x[STS] != 0.0 or om == 0.0:
            if abs(tt) <= c_stat:
                cf = tt
                om_new = 0.0
                x[STS] = 1.0
            else:
                cf = c_stat * _sign(tt)
                om_new = om + dt * (tt - cf) / jeq
                x[STS] = 0.0
        else:
            cf = (CS * (1.0 + STRA * math.exp(-abs(om) / STRV)) + CVISC * abs(om) / tau
                  + roll) * _sign(om)                                   # eq. 5.13-5.14
            om_new = om + dt * (tt - cf) / jeq
            if om_new * om < 0.0:                                       # zero crossing
                om_new = 0.0
                x[STS] = 1.0 if abs(tt) <= c_stat else 0.0
        # ---- double nut (eq. 5.27-5.32) -----------------------------------------------
        fz1 = -pn1 * g                                                 # eq. 5.28
        fz2 = -pn2 * g
        ffr_tot = 0.0
        for j in range(2):
            if j == 0:
                v = x[V1]
                fdrive = Z * fz1 - fpr - 0.5 * fext                     # eq. 5.29, j = 1
                pj = pn1
                st = STN1
            else:
                v = x[V2]
                fdrive = Z * fz2 + fpr - 0.5 * fext                     # eq. 5.29, j = 2
                pj = pn2
                st = STN2
            f_stat = 0.5 * FS + fv * Z * abs(pj)
            if x[st] != 0.0 or v == 0.0:
                if abs(fdrive) <= f_stat:
                    ffr = fdrive
                    v_new = 0.0
                    x[st] = 1.0
                else:
                    ffr = f_stat * _sign(fdrive)
                    v_new = v + dt * (fdrive - ffr) / mhalf
                    x[st] = 0.0
            else:
                ffr = (f_stat + CN * TWO_PI / lead * abs(v)) * _sign(v)  # eq. 5.31-5.32
                v_new = v + dt * (fdrive - ffr) / mhalf
                if v_new * v < 0.0:
                    v_new = 0.0
                    x[st] = 1.0 if abs(fdrive) <= f_stat else 0.0
            if j == 0:
                x[V1] = v_new
            else:
                x[V2] = v_new
            vm = 0.5 * (v + v_new)
            x[E_FRN] += ffr * vm * dt
            x[E_EXT] += 0.5 * fext * vm * dt
            x[E_PR] += (-fpr if j == 0 else fpr) * vm * dt
            ffr_tot += ffr
        # ---- energy bookkeeping of the screw (midpoint speeds) -------------------------
        omm = 0.5 * (om + om_new)
        x[E_FRS] += cf * omm * dt
        x[E_MOT] += x[TQ] / tau * omm * dt
        x[E_ETA] += (x[TQ] / tau - cm) * omm * dt
        # C_V of eq. 5.10 vs the work-consistent lever: power the transmission creates
        x[E_MIS] += Z * (ps1 + ps2) * (lever_kin - lever_v) * omm * dt
        if wearing:        # Archard: dV = (Z k / H) sum|P| (rolling distance per rad) |dOmega|
            acc_w += (abs(ps1) + abs(pn1) + abs(ps2) + abs(pn2)) * abs(omm)
        x[OM] = om_new
        x[TH] += dt * om_new
        x[X1] += dt * x[V1]
        x[X2] += dt * x[V2]
        # ---- sensors (eq. 5.1): LVDT on nut position, encoder on motor speed ------------
        xn = 0.5 * (x[X1] + x[X2])
        if lvdt_first:     # a first-order demodulator, exact over the sub-step
            x[LY] += (xn - x[LY]) * a_l
        else:
            x[LYD] += dt * (ls * ls * (xn - x[LY]) - 2.0 * lz * ls * x[LYD])
            x[LY] += dt * x[LYD]
        x[EYD] += dt * (es * es * (om_new / tau - x[EY]) - 2.0 * ez * es * x[EYD])
        x[EY] += dt * x[EYD]
        x[T] = t + dt
        acc_cf += cf
        acc_ff += ffr_tot
        acc_cv += cv
        acc_v += va
        acc_fe += fext

    inv = 1.0 / nsub
    if wearing:
        x[WEAR_V] += wgain * dt * acc_w
    out[O_FRIC_T] = acc_cf * inv
    out[O_FRIC_F] = acc_ff * inv
    out[O_REACT_T] = acc_cv * inv
    out[O_VOLT] = acc_v * inv
    out[O_FEXT] = acc_fe * inv
    out[O_ILIM] = ilim
    out[O_PMAX1] = pmax1
    out[O_PMAX2] = pmax2
    out[O_PRELOAD] = fpr
    out[O_BACKLASH] = backlash
    out[O_FSCALE] = fscale


# --- sensor vector for measure() ---------------------------------------------------------
S_IGAIN, S_IOFF, S_LGAIN, S_LOFF, S_EGAIN, S_RATIO, S_COUNTS, S_WIN, S_SYNC, S_QUANT = range(10)
NS = 10
# S_WIN: encoder speed window in SYNC periods (0: the sensor filter of eq. 5.1);
# S_SYNC: the SYNC period (s); S_QUANT: 1 = whole counts, 0 = the quantiser's expectation
# over its phase (`sensors.encoder_quantised`)
# --- measurement vector ------------------------------------------------------------------
M_CUR, M_SPEED, M_ANGLE, M_POS, M_TEMP = range(5)
NM = 5


@njit(cache=True, inline="always", error_model="numpy", fastmath=FM)
def _counts_angle(screw_angle: float, s: np.ndarray) -> float:
    """The encoder's motor angle (rad) quantised to whole counts, or (s[S_QUANT] == 0)
    the quantiser's expectation over a uniform phase: floor(a) averages to a - 1/2 counts."""
    counts = s[S_COUNTS]
    a = screw_angle / s[S_RATIO] / TWO_PI * counts
    if s[S_QUANT] == 0.0:
        return (a - 0.5) * TWO_PI / counts
    return math.floor(a) * TWO_PI / counts


@njit(cache=True, error_model="numpy", fastmath=FM)
def measure(x: np.ndarray, s: np.ndarray, noise: np.ndarray, m: np.ndarray) -> None:
    """Sensor readings of state x: current (eq. 5.2), encoder speed and angle, LVDT (eq. 5.1).

    The encoder speed is the second-order filter of eq. 5.1 on the shaft speed, or, with
    a window of N = s[S_WIN] >= 1 SYNC periods, the count difference
    (theta_q[k] - theta_q[k - N]) / (N T) of the quantised angle.
    noise = (current A, position m, speed rad/s) white-noise samples for this SYNC.
    """
    m[M_CUR] = s[S_IGAIN] * x[IM] + s[S_IOFF] + noise[0]
    m[M_ANGLE] = _counts_angle(x[TH], s)
    win = int(s[S_WIN])
    if win > 0:
        old = _counts_angle(x[TH_HIST + win - 1], s)
        m[M_SPEED] = s[S_EGAIN] * (m[M_ANGLE] - old) / (win * s[S_SYNC]) + noise[2]
    else:
        m[M_SPEED] = s[S_EGAIN] * x[EY] + noise[2]
    m[M_POS] = s[S_LGAIN] * x[LY] + s[S_LOFF] + noise[1]
    m[M_TEMP] = x[TEMP]


@njit(cache=True, error_model="numpy", fastmath=FM)
def run_open(x: np.ndarray, p: np.ndarray, u_seq: np.ndarray, out_seq: np.ndarray,
             x_seq: np.ndarray) -> None:
    """Advance len(u_seq) periods with a precomputed input sequence (no controller).

    Used by offline studies that do not need feedback (stiffness calibration, open-loop
    current-demand tests, frequency responses of the drive). x_seq[k] holds the state at
    the end of period k.
    """
    for kk in range(u_seq.shape[0]):
        advance(x, p, u_seq[kk], out_seq[kk])
        x_seq[kk, :] = x
