"""The usage campaign's simulations: actuators with use-driven (Archard) wear,
flown day after day under flight profiles of random severity, with a daily ground test.

One actuator (`actuator_days`), day after day until it fails:

1. **Ground test** (the HUMS's only health input): the thesis' maneuver, the +-0.5 mm
   2 Hz sine for four periods (section 6.4.2; the first phase of the `flight` profile),
   on the ground (no load), full fidelity (10 kHz switching PWM, dynamic balls), sensor
   noise on with a new seed each day, the plant starting from the day's worn volume
   (`wear.initial_volume_m3`). Indexes against the monitoring model (eq. 6.1-6.7): the
   median over periods 2-4 (the first holds the start-up) of Ci, Ci on 15 harmonics,
   friction current and lost motion.
2. **Failure check**: the thesis' failure, Ci (eq. 6.6) below 0.56 (section 6.5), read on
   a noise-free twin of the ground test (run once the noisy Ci on 15 harmonics is below
   `TWIN_START`); the failure time is interpolated linearly in Ci between the last two
   twins. Jams are not modelled by the plant, so no actuator fails by a jam.
3. **Flight**: the seeded `flight` profile (30 s: ground test, take-off, cruise
   turbulence, manoeuvres, landing) at the day's severity (the actuator's mean severity
   x U(0.8, 1.2)), `load.kind=aero`, in the plant's fast mode (averaged PWM, massless
   balls, ~70x real time here: the wear needs the contact forces and the speed, not the
   PWM ripple), Archard wear on. Usage from the flight's trace with `bench.usage`
   (`usage_of_trace`: screw revolutions, load spectrum, Miner life consumed).

**Time compression.** `wear.acceleration` = `ACCELERATION` multiplies every actuator's
Archard coefficient during the flight, so one simulated 30 s flight wears the screw as
much as ACCELERATION x 30 s of real flying at the same severity (the compression is
stated in docs/hums.md with the real hours it stands for). The ground test itself runs
uncompressed. Usage quantities are those of the simulated flight; the Archard exposure the
prognosis uses is proportional to them, so the compression cancels in the exposure-to-
wear coefficient the HUMS learns.

Calibration runs (`sweep_point`): noise-free and noisy ground tests at known worn volumes
(a lab endurance test with teardown measurements): the prognosis' observation model.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from bench.hums import monitor as M
from bench.hums.periods import as_table, period_indexes
from bench.hums.prognosis import exposure_of_usage
from bench.hums.rul import FAILURE
from bench.profiles.catalog import make_profile
from bench.sim.harness import simulate
from plant_rt.params import PlantParams
from plant_rt.paramvalues import seed_in_range

ACCELERATION = 30000.0       # time compression of wear during a simulated flight
FLIGHT_S = 30.0              # one simulated flight a day
PRELOAD_N = 2000.0           # every actuator new at 2 kN (section 6.5's 1-3 kN)
LOG_STD = 0.35               # spread of ln k across the population (campaign's own)
SEVERITY = (0.7, 1.4)        # actuator's mean severity, uniform
SEVERITY_DAY = (0.8, 1.2)    # day-to-day factor on it, uniform
FRICTION = (0.9, 1.1)        # friction scale of a new actuator, uniform
TWIN_START = 0.8             # noisy Ci (15 harmonics) below which the twin runs
MAX_DAYS = 120
GT_INDEXES = ("ci", "ci_harmonic", "friction_current_a", "lost_motion_um")

_NOMINAL: dict[tuple[float, str], Any] = {}


def actuator_params(base: PlantParams, seed: int, healthy: bool = False
                    ) -> tuple[PlantParams, float]:
    """A new actuator of the population: its hidden wear coefficient (drawn by `seed`),
    friction scale, mean severity. Healthy actuators do not wear (k = 0)."""
    rng = np.random.default_rng([int(seed), 77])
    sev = float(rng.uniform(*SEVERITY))
    p = base.with_dict({
        "wear.kind": "archard", "wear.seed": int(seed) % (2**31 - 1),
        "wear.coefficient_log_std": LOG_STD,
        "wear.coefficient_median": 0.0 if healthy else base.wear.coefficient_median,
        "effects.preload_n": PRELOAD_N,
        "effects.friction_scale": float(rng.uniform(*FRICTION)),
        "sensors.noise": True})
    return p, sev


def _nominal(meas: Any, kp: float, params: PlantParams) -> Any:
    """The monitor's nominal ground test (the same every day: set-points only)."""
    key = (kp, params.to_json())
    if key not in _NOMINAL:
        _NOMINAL[key] = M.nominal_for(meas, kp, M.MonitorParams.from_plant(params))
    return _NOMINAL[key]


def ground_test(params: PlantParams, volume_m3: float, kp: float, noise_seed: int | None
                ) -> dict[str, float]:
    """The day's ground test on the worn plant: median indexes over periods 2-4
    (`noise_seed` None: noise-free)."""
    g = params.with_dict({
        "wear.initial_volume_m3": float(volume_m3), "wear.acceleration": 1.0,
        "load.kind": "none", "sensors.noise": noise_seed is not None,
        "sensors.noise_seed": seed_in_range(noise_seed or 0)})
    tr = simulate(make_profile("sine"), g)
    meas = tr.measured()
    nominal_params = PlantParams().with_dict({"effects.preload_n": PRELOAD_N})
    tab = as_table(list(period_indexes(meas, _nominal(meas, kp, nominal_params))))
    out = {}
    for k in GT_INDEXES:
        col = tab["lost_motion_m"] * 1e6 if k == "lost_motion_um" else tab[k]
        out[k] = float(np.nanmedian(col[1:])) if len(col) > 1 else math.nan
    return out


def fly(params: PlantParams, volume_m3: float, severity: float, seed: int,
        acceleration: float = ACCELERATION) -> dict[str, float]:
    """One compressed flight from `volume_m3`: worn volume after it and its usage."""
    from bench.usage import usage_of_trace
    from bench.usage.settings import LOAD_EDGES_N
    f = params.with_dict({
        "wear.initial_volume_m3": float(volume_m3), "wear.acceleration": acceleration,
        "load.kind": "aero", "load.gust_seed": seed_in_range(seed),
        "sensors.noise_seed": seed_in_range(seed),
        "drive.pwm_mode": "averaged", "sim.ball_model": "quasistatic"})
    tr = simulate(make_profile("flight", duration_s=FLIGHT_S, severity=severity,
                               seed=int(seed) % (2**31 - 1)), f)
    u = usage_of_trace(tr, params=f)
    return {"volume_after_m3": float(tr.meta["wear_volume_m3"]),
            "exposure_n_rev": exposure_of_usage(u.load_spectrum_rev, LOAD_EDGES_N),
            "life_consumed": float(u.life_consumed), "revolutions": float(u.screw_revolutions),
            "fm_n": float(u.fm_n)}


def actuator_days(job: dict[str, Any]) -> dict[str, Any]:
    """Worker: one actuator day after day until failure (or `max_days`): per day the
    ground test's indexes, the twin's Ci when run, and the day's flight."""
    p = PlantParams.from_json(job["params"])
    kp, seed, sev_act = job["kp"], int(job["seed"]), float(job["severity"])
    healthy, max_days = bool(job.get("healthy")), int(job.get("max_days", MAX_DAYS))
    rng = np.random.default_rng([seed, 78])
    v = 0.0
    days: list[dict[str, float]] = []
    t_f = math.nan
    prev_twin = math.nan
    for d in range(max_days + 1):
        row: dict[str, float] = {"day": float(d), "volume_m3": v}
        row.update(ground_test(p, v, kp, noise_seed=seed * 1000 + d))
        if not healthy and (row["ci_harmonic"] < TWIN_START or d == max_days):
            ci_true = ground_test(p, v, kp, None)["ci"]
            row["ci_true"] = ci_true
            if ci_true < FAILURE:
                t_f = float(d) if not math.isfinite(prev_twin) else \
                    d - 1 + (prev_twin - FAILURE) / (prev_twin - ci_true)
                days.append(row)
                break
            prev_twin = ci_true
        if healthy or d == max_days:
            days.append(row)
            continue
        sev = float(np.clip(sev_act * rng.uniform(*SEVERITY_DAY), 0.05, 3.0))
        fl = fly(p, v, sev, seed * 1000 + 500 + d, float(job.get("acceleration", ACCELERATION)))
        row.update(severity=sev, **{k: fl[k] for k in ("exposure_n_rev", "life_consumed",
                                                          "revolutions", "fm_n")})
        v = fl["volume_after_m3"]
        days.append(row)
    return {"seed": seed, "healthy": healthy, "severity": sev_act, "t_failure": t_f,
            "acceleration": float(job.get("acceleration", ACCELERATION)),
            "friction_scale": p.effects.friction_scale, "days": days}


def sweep_point(job: dict[str, Any]) -> dict[str, Any]:
    """Worker: a calibration ground test at a known worn volume (noise-free when
    `noise_seed` is None)."""
    p = PlantParams.from_json(job["params"])
    out = ground_test(p, job["volume_m3"], job["kp"], job.get("noise_seed"))
    return {"volume_m3": job["volume_m3"], "noise_seed": job.get("noise_seed"), **out}


def run_jobs(jobs: list[tuple[str, dict[str, Any]]], workers: int | None, progress: bool
             ) -> list[dict[str, Any]]:
    """Every job (("days" | "sweep", job)) on the worker pool, longest first; results in
    job order."""
    from bench.runtime.workers import run_all
    cost = [0.5 if kind == "sweep" else (j.get("max_days", MAX_DAYS) * 0.2 if j.get("healthy")
            else 30.0 / float(j["severity"])) for kind, j in jobs]
    order = sorted(range(len(jobs)), key=lambda k: -cost[k])
    got = run_all(_dispatch, [jobs[k] for k in order], workers, progress,
                  desc="usage campaign", unit="job")
    out: list[Any] = [None] * len(jobs)
    for k, r in zip(order, got, strict=True):
        out[k] = r
    return out


def _dispatch(job: tuple[str, dict[str, Any]]) -> dict[str, Any]:
    kind, j = job
    return sweep_point(j) if kind == "sweep" else actuator_days(j)
