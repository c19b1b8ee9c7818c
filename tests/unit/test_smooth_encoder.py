"""A fit's model has the continuous encoder (`sensors.encoder_quantised` false,
`bench.gap.problem.continuous`): whole counts that close a loop make the cost a step
function of every parameter (docs/gap.md, "A fit that reaches its minimum")."""

import math
from dataclasses import replace

import numpy as np

from bench.gap import effects as E
from bench.gap import problem as P
from bench.gap import resim as R
from bench.gap.cascade import Cascade
from bench.gap.maneuvers import excitation
from bench.harness import simulate
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


def test_continuous_only_where_the_counts_close_a_loop():
    """The bench's own plant (speed by the filter of eq. 5.1, position on the LVDT) keeps
    its counts: they are only in the logged angle, and its results stay bit for bit. A
    count-difference speed, or an identified cascade on the encoder, gets the continuous
    encoder; the measured-current re-simulation (no loop) does not."""
    own = PlantParams().with_dict(R.FAST)
    assert own.sensors.encoder_speed_window == 0
    log = simulate(excitation(0.6), own).measured()
    kept = P.build(log, own, 0.0, bootstrap=1, model_floor=False)
    assert kept.base.sensors.encoder_quantised and not kept.info["smooth_encoder"]
    smooth = P.build(log, COUNTED, 0.0, bootstrap=1, model_floor=False)
    assert not smooth.base.sensors.encoder_quantised and smooth.info["smooth_encoder"]
    enc = Cascade("encoder", 2e5, 0.0, 0.4, 0.0, 300.0, 20.0, 1)
    assert P.build(log, own, 0.0, bootstrap=1, model_floor=False,
                   cascade=enc).info["smooth_encoder"]
    assert not P.build(log, own, 0.0, bootstrap=1, model_floor=False,
                       cascade=replace(enc, source="lvdt")).info["smooth_encoder"]
    assert not P.build(log, COUNTED, 0.0, bootstrap=1, model_floor=False,
                       resim="measured-current").info["smooth_encoder"]
