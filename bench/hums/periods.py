"""HUMS indexes per command period: segmentation of a long trace (`period_indexes`) and
the same from samples pushed as they arrive (`OnlineHums`), with equal numbers."""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any

import numpy as np

from bench import BenchError
from bench.hums import formulas as F
from bench.hums.comparison import Indexes, check_aligned, has_signals
from bench.hums.motion import Kinematics, MotionStream, motion_signals
from bench.hums.spectra import N_HARMONICS, harmonic_amplitudes
from bench.signals.estimators import fundamental_hz
from bench.signals.trace import Trace


def _slice(trace: Trace, sl: slice) -> Trace:
    return Trace({k: v[sl] for k, v in trace.columns.items()}, trace.meta)


def period_indexes(real: Trace, nominal: Trace, period_s: float | None = None,
                   t0_s: float | None = None, n_harmonics: int = N_HARMONICS,
                   kin: Kinematics | None = None) -> Iterator[Indexes]:
    """Indexes of each whole command period of `real` against `nominal`.

    `period_s` defaults to 1 / the trace's ``fundamental_hz``. Periods start at `t0_s`
    (default: the first sample). Within one period the harmonics use a rectangular
    window (the period holds exactly one cycle of f0 and of every harmonic). Lost motion
    and dead time use causal filters run over the whole trace, so they equal what
    `OnlineHums` reports from the same samples pushed live.
    """
    check_aligned(real, nominal)
    real.require(F.CURRENT_SIGNALS + F.POSITION_SIGNALS, "the per-period HUMS indexes")
    if period_s is None:
        f0 = fundamental_hz(real.meta.get("fundamental_hz"))
        if not (math.isfinite(f0) and f0 > 0):
            raise BenchError("per-period indexes need the command period: pass period_s "
                             "or a trace with fundamental_hz metadata")
        period_s = 1.0 / f0
    dt = real.dt
    m = int(round(period_s / dt))
    if m < 8:
        raise BenchError(f"a command period of {period_s:g} s holds fewer than 8 samples")
    t = real.t
    k0 = 0 if t0_s is None else int(np.searchsorted(t, t0_s - 0.5 * dt))
    mot = None
    if has_signals(real, F.LOST_MOTION_SIGNALS) and has_signals(nominal, F.LOST_MOTION_SIGNALS):
        mot = (motion_signals(real, kin), motion_signals(nominal, kin))
    while k0 + m <= len(t):
        sl = slice(k0, k0 + m)
        ms = None if mot is None else tuple(tuple(a[sl] for a in grp) for grp in mot)
        yield one_period(_slice(real, sl), _slice(nominal, sl), period_s, n_harmonics, ms)
        k0 += m


def one_period(r: Trace, nm: Trace, period_s: float, n_harmonics: int,
               mot: Any) -> Indexes:
    """The indexes of one command period `r` against its nominal `nm` (rectangular-window
    harmonics); `mot` = ((d, w_s, v_s) real, (d, w_s, v_s) nominal) of the period, or None."""
    x, xn = r["position_m"], nm["position_m"]
    i, i_n = r["current_a"], nm["current_a"]
    out = Indexes(float(r.t[0]), float(r.t[0] + period_s),
                  mean_error_m=F.mean_error(xn, x), cp=F.cp(xn, x), ci=F.ci(i_n, i),
                  peak_ratio=F.peak_ratio(i_n, i),
                  current_rms_a=float(np.sqrt(np.mean(i * i))),
                  nominal_current_rms_a=float(np.sqrt(np.mean(i_n * i_n))))
    f0 = 1.0 / period_s
    out.harmonics_a = harmonic_amplitudes(i, r.dt, f0, n_harmonics, "rect").tolist()
    out.nominal_harmonics_a = harmonic_amplitudes(i_n, r.dt, f0, n_harmonics, "rect").tolist()
    out.ci_harmonic = F.ci_harmonic(i_n, i, len(i))
    if "motor_speed_rad_s" in r and np.isfinite(r["motor_speed_rad_s"]).all():
        out.friction_current_a = F.friction_current(i, r["motor_speed_rad_s"])
        out.nominal_friction_current_a = F.friction_current(i_n, nm["motor_speed_rad_s"])
    if mot is not None:
        (d, w_s, v_s), (dn, wn_s, vn_s) = mot
        out.lost_motion_m = F.lost_motion_from(d, r["motor_speed_rad_s"])
        out.nominal_lost_motion_m = F.lost_motion_from(dn, nm["motor_speed_rad_s"])
        out.dead_time_s = F.stall_time_from(w_s, v_s, r.dt) - F.stall_time_from(wn_s, vn_s, r.dt)
    return out


def as_table(rows: list[Indexes]) -> dict[str, np.ndarray]:
    """Per-period indexes as columns: t_start_s, t_mid_s, ci, cp, mean_error_m,
    peak_ratio, current RMS, harmonic distortion, lost motion, dead time, h1_a.. and
    nominal_h1_a.. (current harmonic amplitudes, A)."""
    if not rows:
        return {}
    scalars = ("t_start_s", "t_mid_s", "ci", "cp", "mean_error_m", "peak_ratio",
               "current_rms_a", "nominal_current_rms_a", "harmonic_distortion",
               "nominal_harmonic_distortion", "lost_motion_m", "nominal_lost_motion_m",
               "dead_time_s", "ci_harmonic", "friction_current_a",
               "nominal_friction_current_a")
    cols: dict[str, np.ndarray] = {k: np.array([float(getattr(r, k)) for r in rows])
                                   for k in scalars}
    nh = max(len(r.harmonics_a) for r in rows)
    for h in range(nh):
        cols[f"h{h + 1}_a"] = np.array([r.harmonics_a[h] if h < len(r.harmonics_a)
                                        else math.nan for r in rows])
        cols[f"nominal_h{h + 1}_a"] = np.array(
            [r.nominal_harmonics_a[h] if h < len(r.nominal_harmonics_a) else math.nan
             for r in rows])
    return cols


class OnlineHums:
    """Per-command-period indexes from samples pushed as they arrive (live bus runs).

    Push SYNC-rate samples (a dict of equal-length arrays, or scalars, with the measured
    column names); each time a whole command period has arrived, the monitoring model is
    advanced over that period's set-points (its state carries over, so the nominal is the
    one long run's) and the period's `Indexes` are returned. Gives the same numbers as
    `period_indexes` on the whole trace.
    """

    NEED = ("t_s", "setpoint_position_m", "setpoint_speed_rad_s", "mode", "current_a",
            "position_m")

    def __init__(self, period_s: float, position_kp_rad_s_per_m: float | None = None,
                 mparams: Any = None, cparams: Any = None, n_harmonics: int = N_HARMONICS,
                 kin: Kinematics | None = None) -> None:
        from bench.hums.monitor import Monitor, MonitorParams
        self.mparams = mparams or MonitorParams.from_plant()
        self.period_s = float(period_s)
        self.m = int(round(self.period_s / self.mparams.sync_period_s))
        if self.m < 8:
            raise BenchError("the command period must hold at least 8 SYNC periods")
        self.monitor = Monitor(self.mparams, position_kp_rad_s_per_m, cparams)
        self.n_harmonics = n_harmonics
        self.kin = kin
        self._buf: dict[str, list[np.ndarray]] = {}
        self._n = 0
        self._started = False
        self._streams: tuple[MotionStream, MotionStream] | None = None

    def push(self, rows: dict[str, Any]) -> list[Indexes]:
        missing = [k for k in self.NEED if k not in rows]
        if missing:
            raise BenchError(f"online HUMS needs the signal(s) {', '.join(missing)}")
        arrs = {k: np.atleast_1d(np.asarray(v, dtype=float)) for k, v in rows.items()}
        n = len(arrs["t_s"])
        for k, v in arrs.items():
            if len(v) != n:
                raise BenchError(f"online HUMS: column {k!r} has {len(v)} samples, t_s {n}")
        if not self._started:
            x0 = float(arrs["position_m"][0])
            self.monitor.x0_m = x0 if abs(x0) >= 20e-6 else 0.0
            self.monitor.reset()
            if all(k in arrs for k in F.LOST_MOTION_SIGNALS):
                dt = self.mparams.sync_period_s
                self._streams = (MotionStream(dt, self.kin), MotionStream(dt, self.kin))
            self._started = True
        for k, v in arrs.items():
            self._buf.setdefault(k, []).append(v)
        self._n += n
        out = []
        while self._n >= self.m:
            cols = {k: np.concatenate(v) for k, v in self._buf.items()}
            now = {k: v[:self.m] for k, v in cols.items()}
            self._buf = {k: [v[self.m:]] for k, v in cols.items()}
            self._n -= self.m
            out.append(self._period(now))
        return out

    def _period(self, cols: dict[str, np.ndarray]) -> Indexes:
        from bench.hums.monitor import nominal_columns
        mon = self.monitor.run(cols["setpoint_position_m"], cols["setpoint_speed_rad_s"],
                               cols["mode"])
        nom = Trace(nominal_columns(cols["t_s"], cols["setpoint_position_m"],
                             cols["setpoint_speed_rad_s"], cols["mode"], mon))
        real = Trace(dict(cols))
        mot = None
        if self._streams is not None:
            a, b = self._streams
            mot = (a.push(real["motor_angle_rad"], real["position_m"],
                          real["motor_speed_rad_s"]),
                   b.push(nom["motor_angle_rad"], nom["position_m"],
                          nom["motor_speed_rad_s"]))
        return one_period(real, nom, self.period_s, self.n_harmonics, mot)
