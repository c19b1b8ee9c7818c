"""A diagnosis problem: one log, the nominal model, the noise floor and the residuals.

The residual of signal s is r_s = y_log,s - y_sim,s over SYNC samples, normalised by
the signal's floor sigma_s: the RMS residual the nominal model itself leaves when the
only differences are sensor noise of the level measured in the log (a parametric
bootstrap through the closed loop, so noise the loop propagates is included) and, for
the high-fidelity plant, the fast mode's own error against full fidelity on this log.
The normalised energy E_s = mean(r_s^2) / sigma_s^2 is then about 1 when nothing but
noise separates log and model; the excess X = sum_s (E_s - 1) is the gap.

Signals (see `bench.gap.resim.SIGNALS`): current_a (A), motor_speed_rad_s (rad/s),
position_m (LVDT, m), encoder_position_m (encoder angle as nut travel, m).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.ndimage import uniform_filter1d

from bench import BenchError
from bench.gap import resim as R
from bench.gap.autocorr import corr_length
from bench.gap.cascade import Cascade
from bench.gap.effects import Effect
from bench.gap.effects import get as get_effect
from bench.signals.estimators import noise_floor
from bench.signals.trace import MODE_POSITION, MODE_SPEED, Trace
from plant_rt.params import PlantParams

NEEDED = ("t_s", "mode", "current_a", "motor_speed_rad_s", "motor_angle_rad", "position_m")
NOISE_COLS = ("current_a", "position_m", "motor_speed_rad_s")   # plant noise order
FLOORS = {"current_a": 2e-3, "motor_speed_rad_s": 2e-3, "position_m": 2e-8,
          "encoder_position_m": 2e-8}
"""Lowest floors (signal units): resolution-level values for noise-free logs."""

RMAX = 1e4               # normalised residuals are clipped here (a diverging candidate)
MIN_TRAVEL_M = 50e-6      # below this the log has too little motion to identify anything
MIN_SAMPLES = 200
LOOP_CACHE = 64           # re-simulations a problem keeps (`Problem._loop_cols`)


@dataclass
class Problem:
    """Log + nominal model + floors: everything a fit needs (picklable for workers)."""
    base: PlantParams                   # nominal model (fast mode for fitting)
    drive: R.Drive
    meas: dict[str, np.ndarray]         # logged signals (SIGNALS)
    sigma: dict[str, float]             # floor per signal (units of the signal)
    n_fit: int                          # samples [0, n_fit) fit; [n_fit, n) held out
    dt: float
    noise_sigma: dict[str, float] = field(default_factory=dict)
    model_floor: dict[str, float] = field(default_factory=dict)
    sigma_smooth: dict[str, float] = field(default_factory=dict)
    holdout: Problem | None = None      # another log for held-out evaluation
    info: dict[str, Any] = field(default_factory=dict)
    model: str = "plant"                # nominal model name (bench.gap.models)
    friction_split: str = "model"       # where the model's Coulomb friction acts: "model"
                                        # (known) or "unknown" (bench.gap.library.NUT_SHARE)
    full_base: PlantParams | None = None   # the model at the fidelity it was given (the
                                        # fits run `base`, its fast mode), when they differ
    _cache: dict[str, Any] = field(default_factory=dict, repr=False, compare=False)

    @property
    def n(self) -> int:
        return len(self.drive.t)

    @property
    def travel(self) -> float:
        return R.angle_to_travel(self.base)

    # -- simulation --------------------------------------------------------------------
    def params_for(self, effects: Sequence[Effect], thetas: Sequence[dict[str, float]]
                   ) -> PlantParams:
        over: dict[str, Any] = {}
        for eff, th in zip(effects, thetas, strict=True):
            over.update(eff.plant_overrides(th, self.base))
        return self.base.with_dict(over) if over else self.base

    def loop_delays(self, effects: Sequence[Effect], thetas: Sequence[dict[str, float]]
                    ) -> tuple[int, int]:
        """Extra whole-period delays of the LVDT and of the encoder in the loop that
        `effects` at `thetas` ask for (`Effect.loop_delays`), summed."""
        dl = de = 0
        for eff, th in zip(effects, thetas, strict=True):
            a, b = eff.loop_delays(th, self.dt)
            dl, de = dl + a, de + b
        return dl, de

    def simulate(self, effects: Sequence[Effect] = (), thetas: Sequence[dict[str, float]] = (),
                 n: int | None = None, noise: np.ndarray | None = None
                 ) -> dict[str, np.ndarray]:
        """Closed-loop re-simulation with `effects` at `thetas`; logged-signal columns.
        Effects that act on the log alone re-use the nominal re-simulation (kept per
        length); `noise` (n, 3): sensor noise as `closed_loop` takes it."""
        params = self.params_for(effects, thetas)
        delays = self.loop_delays(effects, thetas)
        if params is self.base and delays == (0, 0) and noise is None:
            cols = self._nominal_cols(n)
        elif noise is None:
            cols = self._loop_cols(params, n, delays)
        else:
            cols = self.closed_loop(params, n, noise, delays)
        for eff, th in zip(effects, thetas, strict=True):
            if eff.in_log(self.base):
                cols = eff.post(cols, th, self.dt)
        return self.signals(cols)

    def _nominal_cols(self, n: int | None) -> dict[str, np.ndarray]:
        """The nominal re-simulation's columns over the first `n` samples, simulated once
        per model and length (a later change of `base` is a new key): the fit part's and
        the whole log's are both kept (an effect on the log alone asks for each in turn)."""
        length = self.n if n is None else min(n, self.n)
        store = self._cache.get("nominal")
        if not isinstance(store, dict) or store.get("base") is not self.base:
            store = {"base": self.base}
            self._cache["nominal"] = store
        hit = store.get(length)
        if hit is None:
            hit = store[length] = self.closed_loop(self.base, n)
        return dict(hit)

    def _resumable(self) -> bool:
        """Whether this problem's re-simulation can go on from a kept state (`resim.Resume`):
        the bench's plant in its closed loop (not the measured-current replay, which
        corrects its demand over the whole run, nor another model)."""
        return self.model == "plant" and self.drive.resim == "closed-loop"

    def _loop_cols(self, params: PlantParams, n: int | None, delays: tuple[int, int]
                   ) -> dict[str, np.ndarray]:
        """The noise-free re-simulation's columns with `params` and `delays` over the
        first `n` samples, from the last LOOP_CACHE ones of this problem when it ran them
        already (the same values, the same columns: a fit evaluates its start, its first
        least-squares point and its optimum more than once, and candidates meet at the
        same values). Keyed by the model, the values (exact: repr), the length and the
        delays, for this drive; copies in and out, so no caller sees another's arrays;
        the least recently used goes first (a pair's fits all start from its single's
        optimum). A run shorter than the log keeps its state before its last period, and a longer
        run of the same values goes on from there (`resim.Resume`): a fit's optimum on
        the fit part, then on the whole log for the held-out energies, costs the held-out
        part only, with the columns of a run from the start."""
        length = self.n if n is None else min(n, self.n)
        dl = tuple(int(d) for d in delays)
        key = (self.model, repr(params), length, dl)
        store = self._cache.setdefault("loops", {})
        hit = store.get(key)
        if hit is not None and hit[0] is self.drive:
            try:                             # the last used goes last: evicted last
                store[key] = store.pop(key)
            except KeyError:                 # another thread's eviction
                pass
            return {c: v.copy() for c, v in hit[1].items()}
        kept = self._cache.setdefault("resume", {})
        rkey = (self.model, key[1], dl)
        keep: dict[str, Any] | None = None
        resume = None
        if self._resumable():
            prior = kept.get(rkey)
            if prior is not None and prior[0] is self.drive and prior[1].k < length:
                resume = prior[1]
            if length < self.n:
                keep = {}
        cols = self.closed_loop(params, n, None, delays, keep=keep, resume=resume)
        store[key] = (self.drive, {c: v.copy() for c, v in cols.items()})
        if keep and "state" in keep:
            kept[rkey] = (self.drive, keep["state"])
        for d in (store, kept):
            while len(d) > LOOP_CACHE:       # the oldest (least recently used) out
                try:
                    del d[next(iter(d))]
                except (KeyError, RuntimeError, StopIteration):   # another thread's eviction
                    break
        return cols

    def closed_loop(self, params: PlantParams, n: int | None = None,
                    noise: np.ndarray | None = None,
                    delays: tuple[int, int] = (0, 0), keep: dict[str, Any] | None = None,
                    resume: Any = None) -> dict[str, np.ndarray]:
        """The nominal model's closed-loop re-simulation with `params` (`delays`: the
        LVDT's and the encoder's extra periods in the loop, `bench.gap.delays`; `keep`,
        `resume`: `resim.closed_loop`'s, the bench's plant only)."""
        if self.model == "plant":
            return R.closed_loop(params, self.drive, n, noise=noise, delays=delays, keep=keep,
                                 resume=resume)
        from bench.gap.models import closed_loop_of
        cols = closed_loop_of(self.model)(params, self.drive, n, noise=noise)
        return R.shift_columns(cols, *delays) if delays != (0, 0) else cols

    def signals(self, cols: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """Logged-style columns -> the compared signals (encoder angle as nut travel: the
        absolute angle times tau p / 2 pi, or, for a relative encoder, the travel since
        the first sample added to the initial LVDT reading)."""
        ang = cols["motor_angle_rad"]
        out = {s: cols[s] for s in ("current_a", "motor_speed_rad_s", "position_m")}
        if self.drive.x0_true_m is not None:
            out["encoder_position_m"] = ang * self.travel
        else:
            out["encoder_position_m"] = (ang - ang[0]) * self.travel + self.drive.x0_m
        if "current_demand_a" in cols:
            out["current_demand_a"] = cols["current_demand_a"]
        return out

    # -- residuals -----------------------------------------------------------------------
    def residual(self, sim: dict[str, np.ndarray], lo: int, hi: int) -> np.ndarray:
        """Normalised residuals of samples [lo, hi), signals stacked."""
        parts = []
        for s in R.SIGNALS:
            r = (self.meas[s][lo:hi] - sim[s][lo:hi]) / self.sigma[s]
            parts.append(np.clip(np.nan_to_num(r, nan=RMAX, posinf=RMAX, neginf=-RMAX),
                                 -RMAX, RMAX))
        return np.concatenate(parts)

    def energies(self, sim: dict[str, np.ndarray], lo: int, hi: int) -> dict[str, float]:
        """Normalised energy E_s = mean(r_s^2)/sigma_s^2 per signal over [lo, hi)."""
        out = {}
        for s in R.SIGNALS:
            r = (self.meas[s][lo:hi] - sim[s][lo:hi]) / self.sigma[s]
            r = np.clip(np.nan_to_num(r, nan=RMAX, posinf=RMAX, neginf=-RMAX), -RMAX, RMAX)
            out[s] = float(np.mean(r ** 2)) if hi > lo else float("nan")
        return out

    def energies_smooth(self, sim: dict[str, np.ndarray], lo: int, hi: int) -> dict[str, float]:
        """Normalised energy of the smoothed residual (10-sample moving average) against
        the smoothed floor: more sensitive to slow, systematic gaps than `energies`."""
        out = {}
        for s in R.SIGNALS:
            d = np.clip(np.nan_to_num(self.meas[s] - sim[s], nan=RMAX * self.sigma[s],
                                      posinf=RMAX * self.sigma[s],
                                      neginf=-RMAX * self.sigma[s]),
                        -RMAX * self.sigma[s], RMAX * self.sigma[s])
            r = smooth(d)[lo:hi]
            out[s] = float(np.mean(r ** 2)) / self.sigma_smooth[s] ** 2 if hi > lo \
                else float("nan")
        return out

    def excess(self, sim: dict[str, np.ndarray], lo: int, hi: int) -> float:
        """Gap excess X = sum_s (E_s - 1) over [lo, hi) (0 at the noise floor)."""
        return float(sum(e - 1.0 for e in self.energies(sim, lo, hi).values()))


# --- building a problem from a trace ----------------------------------------------------

def noise_std(y: np.ndarray) -> float:
    """White-noise standard deviation of `y` from its second difference (robust MAD):
    var(d2 y) = 6 sigma^2 for white noise; smooth motion barely contributes at 1 kHz.
    The one estimator of the bench (`bench.signals.estimators.noise_floor`), 0.0 below 10
    finite samples (a fit's weight, where the floor's NaN would poison the cost)."""
    y = np.asarray(y, float)
    y = y[np.isfinite(y)]
    return noise_floor(y) if len(y) >= 10 else 0.0


MAX_GAP_FRACTION = 0.02   # lost SYNC rows (NaN) tolerated and interpolated
GAP_COLUMNS = ("setpoint_position_m", "setpoint_speed_rad_s", "mode", "current_demand_a",
               "current_a", "motor_speed_rad_s", "motor_angle_rad", "position_m",
               "load_force_n")


def fill_gaps(trace: Trace, purpose: str = "gap diagnosis") -> Trace:
    """A copy with short runs of missing rows (lost SYNCs, missing frames: NaN)
    interpolated (mode: previous value), counted in ``meta["bridged"]`` (signal ->
    samples); BenchError when more than MAX_GAP_FRACTION of a signal is missing, when a
    run is longer than `bench.hums.indexes.BRIDGE_MAX_SAMPLES` (the re-simulation
    compares every SYNC period: a longer bridge, in the set-points or in a sensor, would
    itself be a gap), or when the log holds several runs (NMT restarts: the plant state
    does not carry over)."""
    from bench.hums.indexes import BRIDGE_MAX_SAMPLES, bridge, signal_gaps
    if "run" in trace and len(np.unique(trace["run"][np.isfinite(trace["run"])])) > 1:
        raise BenchError(f"{purpose}: the log holds "
                         f"{len(np.unique(trace['run'][np.isfinite(trace['run'])]))} runs "
                         "(the node was restarted); diagnose one run at a time")
    gaps = signal_gaps(trace, GAP_COLUMNS)
    for c, g in gaps.items():
        if g.missing > MAX_GAP_FRACTION * g.n:
            raise BenchError(f"{purpose}: {100 * g.missing / g.n:.1f} % of {c} is missing "
                             f"(lost frames); at most {100 * MAX_GAP_FRACTION:.0f} % can be "
                             "interpolated")
        if g.longest[1] > BRIDGE_MAX_SAMPLES:
            raise BenchError(f"{purpose}: {g.describe(trace.t)}: the re-simulation "
                             "compares every SYNC period; diagnose the part of the log "
                             "before or after the gap")
    out = bridge(trace, gaps)
    out.meta["bridged"] = {c: g.missing for c, g in gaps.items()}
    return out


def check_log(trace: Trace, purpose: str = "gap diagnosis") -> None:
    """Raise a BenchError saying what the log lacks (set-point, signals, motion)."""
    if len(trace) < MIN_SAMPLES:
        raise BenchError(f"{purpose} needs at least {MIN_SAMPLES} samples; the log has "
                         f"{len(trace)}")
    has_pos = "setpoint_position_m" in trace and np.isfinite(trace.columns[
        "setpoint_position_m"]).any()
    has_spd = "setpoint_speed_rad_s" in trace and np.isfinite(trace.columns[
        "setpoint_speed_rad_s"]).any()
    if not (has_pos or has_spd):
        raise BenchError(f"{purpose} re-simulates the run from its set-point, but the log has "
                         "no set-point (setpoint_position_m or setpoint_speed_rad_s): log the "
                         "ECU set-point and mode, or import them with `bench import`")
    trace.require(NEEDED, purpose)
    mode = trace["mode"]
    if has_pos is False and np.any(mode == MODE_POSITION):
        raise BenchError(f"{purpose}: the log is in position mode but has no "
                         "setpoint_position_m")
    if has_spd is False and np.any(mode == MODE_SPEED):
        raise BenchError(f"{purpose}: the log is in speed mode but has no "
                         "setpoint_speed_rad_s")
    t = trace.t
    d = np.diff(t)
    if np.any(d <= 0):
        raise BenchError(f"{purpose}: time stamps must increase strictly (resample with "
                         "`bench import`)")
    if np.max(np.abs(d - np.median(d))) > 0.05 * np.median(d):
        raise BenchError(f"{purpose}: samples are not at a fixed SYNC rate (median "
                         f"{np.median(d) * 1e3:.3g} ms); resample with `bench import`")
    if not np.any(mode != 0):
        raise BenchError(f"{purpose}: the ECU is idle (mode 0) through the whole log, so "
                         "nothing was commanded")
    pos = trace["position_m"]
    travel = float(np.nanmax(pos) - np.nanmin(pos))
    if travel < MIN_TRAVEL_M:
        raise BenchError(f"{purpose}: too little motion to identify anything: the nut "
                         f"travelled {travel * 1e6:.1f} um (needs at least "
                         f"{MIN_TRAVEL_M * 1e6:.0f} um with reversals, accelerations and "
                         "dwells)")


def under_controller(trace: Trace, controller: Any) -> None:
    """Name a calibration's `controller` entry in `trace`'s metadata, so that `drive_of`
    re-simulates the log under it; a log that names its own, or a controller that is the
    bench's ECU (the default), is left as it is."""
    if (isinstance(controller, dict) and controller.get("method", "bench-ecu") != "bench-ecu"
            and "controller" not in trace.meta):
        trace.meta["controller"] = controller


def drive_of(trace: Trace, encoder: str = "absolute",
             params: PlantParams | None = None, resim: str = "closed-loop",
             cascade: Any = None) -> R.Drive:
    """The re-simulation drive of `trace`: set-points, mode, demand, initial position and,
    when the log has a load cell (`load_force_n`), the axial load replayed into the plant.

    encoder "absolute": the encoder angle is zero with the nut at zero (the bench's
    plant, multi-turn encoders, resolvers with a homed zero), so the initial nut position
    is angle x tau p / 2 pi and an LVDT offset is observable; "relative": the initial
    position is the median LVDT reading of the first 20 samples.
    resim: `bench.gap.resim.RESIMS` (measured-current: the logged current and encoder
    angle drive the re-simulation instead of the bench's ECU); cascade: an identified
    controller (`bench.gap.cascade.Cascade`) in the ECU's place. Without either, a log
    whose metadata names its controller (``meta["controller"]``: a calibration's
    `controller` entry, `bench.gap.calibrate`) is re-simulated under that one.
    """
    if encoder not in ("absolute", "relative"):
        raise BenchError(f"encoder reference must be absolute or relative, not {encoder!r}")
    if resim not in R.RESIMS:
        raise BenchError(f"re-simulation must be one of {', '.join(R.RESIMS)}, not {resim!r}")
    ctrl = trace.meta.get("controller")
    if cascade is None and resim == "closed-loop" and isinstance(ctrl, dict):
        if ctrl.get("cascade"):
            cascade = Cascade.from_dict(ctrl["cascade"])
        elif ctrl.get("method") == "measured-current":
            resim = "measured-current"
    n = len(trace)
    col = trace.columns

    def get(name: str) -> np.ndarray:
        v = col.get(name)
        return np.zeros(n) if v is None else np.nan_to_num(np.asarray(v, float))

    demand = col.get("current_demand_a")
    pos = np.asarray(col["position_m"], float)
    x0 = float(np.nanmedian(pos[:20]))
    x0_true = None
    if encoder == "absolute":
        x0_true = float(col["motor_angle_rad"][0]) * R.angle_to_travel(params or PlantParams())
    load = col.get("load_force_n")
    if load is not None and not np.isfinite(load).any():
        load = None
    by_current = resim == "measured-current"
    return R.Drive(trace.t - trace.t[0], get("setpoint_position_m"), get("setpoint_speed_rad_s"),
                   np.round(get("mode")), np.full(n, np.nan) if demand is None
                   else np.asarray(demand, float), x0, x0_true,
                   None if load is None else get("load_force_n"), resim=resim,
                   current_meas=get("current_a") if by_current else None,
                   angle_meas=get("motor_angle_rad") if by_current else None,
                   cascade=cascade)


def continuous(params: PlantParams) -> PlantParams:
    """`params` with the encoder's quantiser replaced by its expectation over the phase
    (`sensors.encoder_quantised` false: angle - half a count), unchanged otherwise."""
    if not params.sensors.encoder_quantised:
        return params
    return params.with_dict({"sensors.encoder_quantised": False})


def counts_in_loop(params: PlantParams, drive: R.Drive) -> bool:
    """Whether the encoder's whole counts close a loop when `drive` re-simulates `params`:
    a speed taken as the count difference (`sensors.encoder_speed_window` > 0) under a
    controller, or an identified cascade whose position loop reads the encoder. Not the
    measured-current re-simulation (no loop), nor the speed filter of eq. 5.1 with the
    position on the LVDT (the bench's own plant: the counts are only in the logged angle)."""
    if drive.resim == "measured-current":
        return False
    if params.sensors.encoder_speed_window > 0:
        return True
    return drive.cascade is not None and drive.cascade.source == "encoder"


def with_rate(base: PlantParams, dt: float) -> PlantParams:
    """`base` with its SYNC period set to the log's sample period."""
    if math.isclose(dt, base.sim.sync_period_s, rel_tol=1e-3):
        return base
    return base.with_dict({"sim.sync_period_s": round(dt, 9)})


def estimate_noise(p: Problem, cols: dict[str, np.ndarray], iterations: int = 3,
                   seed: int = 999, sensor: PlantParams | None = None) -> dict[str, float]:
    """Sensor noise standard deviations (A, m, rad/s) that reproduce the log's
    high-frequency content through the nominal closed loop.

    The second-difference estimate of a logged signal also holds noise the loop carries
    from the other sensors (LVDT noise -> position loop -> demand -> current), so the
    levels are matched by simulation: sigma <- sigma sqrt(V_log / V_sim), a few times.
    """
    target = {c: max(noise_std(cols[c]), FLOORS[c] / 4) for c in NOISE_COLS}
    sig = dict(target)
    rng = np.random.default_rng(seed)
    n = p.n
    for _ in range(iterations):
        z = rng.standard_normal((n, 3)) * np.array([sig[c] for c in NOISE_COLS])
        sim = p.closed_loop(p.base if sensor is None else sensor, noise=z)
        for c in NOISE_COLS:
            v = max(noise_std(sim[c]), 1e-30)
            sig[c] = max(sig[c] * min(max(target[c] / v, 0.2), 5.0), FLOORS[c] / 4)
    return sig


def _own_fidelity(base: PlantParams, smooth_encoder: bool) -> PlantParams | None:
    """The noise-free model at the fidelity it was given (the encoder continuous with
    `smooth_encoder`), or None when that is the fits' fast mode already."""
    full = base.with_dict({"sensors.noise": False})
    full = continuous(full) if smooth_encoder else full
    if full.drive.pwm_mode != "averaged" or full.sim.ball_model != "quasistatic":
        return full
    return None


_FLOOR_THREAD = ThreadPoolExecutor(1, thread_name_prefix="bench-gap-floor")
"""Runs a build's model floor beside its noise floor (`build`); no thread until used."""


def build(trace: Trace, base: PlantParams, holdout_frac: float = 0.5,
          bootstrap: int = 6, model_floor: bool = True, seed: int = 12345,
          encoder: str = "absolute", purpose: str = "gap diagnosis",
          model: str = "plant", resim: str = "closed-loop", cascade: Any = None,
          smooth_encoder: bool = True, friction_split: str = "model") -> Problem:
    """A Problem for `trace` against the nominal `base` (made fast-mode here).

    With `smooth_encoder` (default), the model every fit, nominal and held-out evaluation
    simulates has the continuous encoder (`continuous`): whole counts make the
    re-simulation, and so the cost, a step function of every parameter, whether they
    close a loop (`counts_in_loop`) or are only logged (the bench's own plant: its
    encoder's travel is the signal that carries backlash and friction most sharply, and
    a count flips under a change of a tenth of a micrometre), so a finite-difference
    Jacobian sees steps, the fit stops where it starts, and its intervals are not the
    cost's (docs/gap.md, "Fitting").

    Floors: sensor noise is estimated from the log (`estimate_noise`) and pushed through
    the nominal closed loop with the sensors as declared (whole counts) `bootstrap` times
    (seeded), against the fit's noise-free nominal: the encoder's quantisation and the
    quantised loop's dither are in the floor; with `model_floor`, the difference between
    the fast and the full-fidelity nominal plant on this log is added (squares).
    """
    trace = fill_gaps(trace, purpose)
    check_log(trace, purpose)
    dt = trace.dt
    base = with_rate(base, dt)
    sensor = base.with_dict({**R.FAST, "sensors.noise": False})   # the sensors as declared
    drive = drive_of(trace, encoder, sensor, resim, cascade)
    fast = continuous(sensor) if smooth_encoder else sensor       # what every fit simulates
    p = Problem(fast, drive, {}, {}, 0, dt, model=model, friction_split=friction_split)
    cols = {c: np.asarray(trace[c], float) for c in
            ("current_a", "motor_speed_rad_s", "motor_angle_rad", "position_m")}
    if "current_demand_a" in trace:
        cols["current_demand_a"] = np.asarray(trace["current_demand_a"], float)
    p.meas = p.signals(cols)
    n = len(trace)
    p.n_fit = max(MIN_SAMPLES // 2, min(n, int(round(n * (1.0 - holdout_frac)))))
    # -- noise floor ---------------------------------------------------------------------
    # the model at its own fidelity (the model floor below) runs in a thread meanwhile:
    # its compiled loop releases the GIL, and it needs nothing the noise floor computes
    full = _own_fidelity(base, smooth_encoder) if model_floor and model == "plant" else None
    hi_run = _FLOOR_THREAD.submit(R.closed_loop, full, drive) if full is not None else None
    ns = estimate_noise(p, cols, sensor=sensor)
    p.noise_sigma = ns
    nominal = p.simulate()
    rng = np.random.default_rng(seed)
    boot = []
    noisy_cols = []
    for b in range(bootstrap):    # the sensors as declared (whole counts) against the fit's
        z = rng.standard_normal((n, 3)) * np.array([ns[c] for c in NOISE_COLS])
        nc = p.closed_loop(sensor, noise=z)    # model: the quantisation is in the floor
        if b < 2:
            noisy_cols.append(nc)
        noisy = p.signals(nc)
        boot.append({s: noisy[s] - nominal[s] for s in R.SIGNALS})
    mf = {s: 0.0 for s in R.SIGNALS}
    if hi_run is not None:
        p.full_base = full
        hi = p.signals(hi_run.result())
        mf = {s: float(np.sqrt(np.mean((hi[s] - nominal[s]) ** 2))) for s in R.SIGNALS}
    p.model_floor = mf
    p.sigma = {s: float(math.sqrt(np.mean([np.mean(b[s] ** 2) for b in boot])
                                  + mf[s] ** 2 + FLOORS[s] ** 2)) for s in R.SIGNALS}
    p.sigma_smooth = {s: float(math.sqrt(np.mean([np.mean(smooth(b[s]) ** 2) for b in boot])
                                         + mf[s] ** 2 + FLOORS[s] ** 2)) for s in R.SIGNALS}
    p.info["nominal"] = nominal
    p.info["nominal_cols"] = {c: v.copy() for c, v in p._nominal_cols(None).items()}
    p.info["smooth_encoder"] = smooth_encoder
    p.info["noisy_cols"] = noisy_cols
    p.info["bootstrap"] = boot
    p.info["bootstrap_energy"] = [
        {s: float(np.mean(b[s] ** 2)) / p.sigma[s] ** 2 for s in R.SIGNALS} for b in boot]
    p.info["corr_smooth"] = {s: float(np.mean([corr_length(smooth(b[s]), max_lag=2000)
                                               for b in boot])) for s in R.SIGNALS}
    p.info["bootstrap_energy_smooth"] = [
        {s: float(np.mean(smooth(b[s]) ** 2)) / p.sigma_smooth[s] ** 2 for s in R.SIGNALS}
        for b in boot]
    return p


SMOOTH_S = 0.01


def smooth(y: np.ndarray, w: int = 10) -> np.ndarray:
    """Centred moving average over `w` samples (edges padded): keeps the systematic,
    slow part of a residual and divides white noise's energy by about `w`."""
    if w <= 1 or len(y) < w:
        return np.asarray(y, float).copy()
    return uniform_filter1d(np.asarray(y, float), w, mode="nearest")


def not_representable(p: Problem, names: Sequence[str], n: int = 1000) -> list[str]:
    """Candidates whose mid-range values leave model `p.model` unchanged (it does not
    read the parameters they act through)."""
    ref = p.simulate([], [], n)
    out = []
    for name in names:
        eff = get_effect(name)
        if eff.where == "log":
            continue
        same = True
        for u in (0.3, 0.7):
            th = {q.name: q.from_unit(u) for q in eff.params}
            sim = p.simulate([eff], [th], n)
            same = same and all(np.array_equal(sim[s], ref[s]) for s in R.SIGNALS)
        if same:
            out.append(name)
    return out
