"""A fit's model has the continuous encoder (`sensors.encoder_quantised` false,
`bench.gap.problem.continuous`): whole counts that close a loop make the cost a step
function of every parameter (docs/gap.md, "Fitting")."""

import math

import numpy as np

from bench.gap import effects as E
from bench.gap import problem as P
from bench.gap import resim as R
from bench.profiles.catalog import make_profile
from bench.profiles.maneuvers import excitation
from bench.sim.harness import simulate
from plant_rt import kernel as K
from plant_rt.model import sensor_vector
from plant_rt.params import PlantParams

# the count-difference speed over 4 SYNC periods closes the ECU's speed loop on the counts
COUNTED = PlantParams().with_dict({**R.FAST, "sensors.encoder_speed_window": 4,
                                   "sensors.encoder_counts_per_rev": 4096})


def test_continuous_angle_is_the_quantisers_mean_over_its_phase():
    p = PlantParams()
    assert p.sensors.encoder_quantised             # the sensor: whole counts
    sq, sc = sensor_vector(p), sensor_vector(P.continuous(p))
    q = 2 * math.pi / p.sensors.encoder_counts_per_rev
    rng = np.random.default_rng(4)
    base = 123.4567 * q
    phases = (np.arange(4000) + 0.5) / 4000 * q   # uniform over one count
    mean_q = np.mean([K._counts_angle((base + f) * p.reducer.ratio, sq) for f in phases])
    mean_c = np.mean([K._counts_angle((base + f) * p.reducer.ratio, sc) for f in phases])
    assert abs(mean_q - mean_c) < 1e-3 * q
    a = float(rng.uniform(-50, 50))
    assert math.isclose(K._counts_angle(a * p.reducer.ratio, sc), a - 0.5 * q,
                        rel_tol=0, abs_tol=1e-9)
    assert K._counts_angle(a * p.reducer.ratio, sq) != K._counts_angle(a * p.reducer.ratio, sc)


def _costs(smooth_encoder: bool) -> np.ndarray:
    log = simulate(excitation(1.5), COUNTED.with_dict(
        {"sensors.noise": True, "sensors.noise_seed": 5, "effects.friction_scale": 1.3}))
    p = P.build(log.measured(), COUNTED, 0.0, bootstrap=2, model_floor=False,
                smooth_encoder=smooth_encoder)
    eff = E.get("friction").for_model(p.base)
    out = []
    for v in np.linspace(1.10, 1.25, 16):      # below the log's 1.3: the cost falls
        r = p.residual(p.simulate([eff], [{"friction_scale": v}], p.n_fit), 0, p.n_fit)
        out.append(float(r @ r) / len(r))
    return np.array(out)


def test_cost_is_smooth_with_the_continuous_encoder():
    """Friction x1.10 ... x1.25 (1 % steps) against a log with x1.3: the fit's cost falls
    monotonically; with the counts in the fit's loop it jumps up and down (a finite
    difference sees noise, not the slope)."""
    smooth = np.diff(_costs(True))
    assert np.all(smooth < 0), smooth
    rough = np.diff(_costs(False))
    assert np.sum(rough > 0) >= 3                  # the quantised loop: rough
    assert np.max(np.abs(rough)) > 5 * np.max(np.abs(smooth))


def test_continuous_encoder_for_every_log():
    """Every fit's model has the continuous encoder, the bench's own plant too (its counts
    are only in the logged angle, but that angle's travel is the signal that carries
    backlash and friction most sharply): a count flips under a tenth of a micrometre, so
    with the counts the fit's cost is a step function there as well. The floor keeps the
    declared counts (the bootstrap simulates the sensors as declared)."""
    own = PlantParams().with_dict(R.FAST)
    assert own.sensors.encoder_speed_window == 0
    log = simulate(excitation(0.6), own).measured()
    for params, kw in ((own, {}), (COUNTED, {}), (COUNTED, {"resim": "measured-current"})):
        p = P.build(log, params, 0.0, bootstrap=1, model_floor=False, **kw)
        assert not p.base.sensors.encoder_quantised and p.info["smooth_encoder"]
    kept = P.build(log, own, 0.0, bootstrap=1, model_floor=False, smooth_encoder=False)
    assert kept.base.sensors.encoder_quantised


def _friction_costs(smooth_encoder: bool) -> np.ndarray:
    own = PlantParams().with_dict(R.FAST)
    log = simulate(make_profile("sine", cycles=6), own.with_dict(
        {"sensors.noise": True, "sensors.noise_seed": 12, "effects.backlash_m": 50e-6,
         "effects.friction_scale": 2.5}))
    p = P.build(log.measured(), own, 0.5, bootstrap=2, model_floor=False,
                smooth_encoder=smooth_encoder)
    effs = [E.get("backlash"), E.get("friction")]
    out = []
    for v in np.linspace(2.2, 2.3, 21):           # 0.2 % steps below the log's 2.5
        r = p.residual(p.simulate(effs, [{"backlash_m": 50e-6}, {"friction_scale": v}],
                                  p.n_fit), 0, p.n_fit)
        out.append(float(r @ r))
    return np.array(out)


def _roughness(costs: np.ndarray) -> float:
    """RMS of the costs about the parabola through them, over their range."""
    x = np.arange(len(costs))
    fit = np.polyval(np.polyfit(x, costs, 2), x)
    return float(np.sqrt(np.mean((costs - fit) ** 2)) / np.ptp(costs))


def test_cost_is_smooth_in_friction_on_the_benchs_own_plant():
    """The demo's worn actuator (backlash 50 um, friction x2.5, the 2 Hz sine) on the
    bench's own plant, where the counts close no loop: friction x2.20 ... x2.30 in 0.2 %
    steps. With the continuous encoder the cost is a parabola within 2 % of its range
    (1 % measured); with the counts it steps up and down about it (6 %) (a fit started beside its minimum
    stopped there: the demo's friction interval [2.22, 2.34] excluded the true 2.5)."""
    smooth, rough = _roughness(_friction_costs(True)), _roughness(_friction_costs(False))
    assert smooth < 0.02, smooth
    assert rough > 0.04 and rough > 3 * smooth, (rough, smooth)
