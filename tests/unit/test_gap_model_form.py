"""The model-form term of the verdict's intervals (`bench.gap.modelform`): the verdict's
candidate fitted on the calibration's held-out healthy log departs from no effect by d
([0, 1] coordinates); the covariance becomes cov_u + d d^T and the intervals follow from
it; the friction size's interval takes the healthy fit's own friction size s_h instead,
var ln(size) + ln(s_h)^2. Without a healthy log nothing changes."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bench.gap import modelform as MF
from bench.gap.diagnose import Options, diagnose
from bench.gap.fit import Fit
from bench.gap.library import Friction
from bench.gap.resim import FAST
from bench.profiles.maneuvers import compact
from bench.sim.harness import simulate
from plant_rt.params import PlantParams


def _fit(value: float, sd_u: float) -> Fit:
    eff = Friction()
    prm = eff.params[0]
    u = prm.to_unit(value)
    ci = {prm.name: (prm.from_unit(u - 1.96 * sd_u), prm.from_unit(u + 1.96 * sd_u))}
    return Fit(("friction",), [{prm.name: value}], [ci], 1.0, 100, 1, 10, objs=[eff],
               cov_u=np.array([[sd_u ** 2]]), free=[(0, prm.name)])


def test_the_interval_widens_by_the_healthy_departure_in_quadrature():
    f = _fit(2.0, 0.01)
    prm = f.objs[0].params[0]
    healthy = Fit(("friction",), [{prm.name: 1.3}], [{}], 1.0, 100, 1, 10)

    class P:                                   # what `departure` reads: the nominal model
        base = PlantParams()

    d = MF.departure(P(), f, healthy)           # type: ignore[arg-type]
    assert d[0] == pytest.approx(prm.to_unit(1.3) - prm.to_unit(1.0))
    g = MF.widened(f, d)
    sd = math.sqrt(0.01 ** 2 + d[0] ** 2)
    u = prm.to_unit(2.0)
    lo, hi = g.ci95[0][prm.name]
    assert lo == pytest.approx(prm.from_unit(u - 1.96 * sd))
    assert hi == pytest.approx(prm.from_unit(u + 1.96 * sd))
    assert g.cov_u[0, 0] == pytest.approx(0.01 ** 2 + d[0] ** 2)
    # in ln(scale): half-width 1.96 sqrt(sd^2 + d^2), wider than both the noise's and |d|
    half = 0.5 * math.log(hi / lo)
    assert half > 1.96 * 0.01 * math.log(prm.hi / prm.lo)
    assert half > math.log(1.3)
    assert f.ci95[0][prm.name] != g.ci95[0][prm.name]       # `f` itself is not changed


def test_no_departure_or_no_healthy_log_leaves_the_fit_as_it_is():
    f = _fit(2.0, 0.01)
    assert MF.widened(f, np.zeros(1)) is f
    for ref in (None, {"name": "cal", "level": None}, {"healthy_logs": []}):
        g, info = MF.apply(None, f, ref, PlantParams(), 0.5, 6, "absolute",  # type: ignore[arg-type]
                           "plant", "model")
        assert g is f and info is None


def _log(friction: float, seed: int):
    p = PlantParams().with_dict({**FAST, "sensors.noise": True, "sensors.noise_seed": seed,
                                 "effects.friction_scale": friction})
    return simulate(compact(), p).measured()


def test_a_model_off_by_a_healthy_friction_gets_the_truth_back_inside():
    """The actuator's healthy friction is 1.3 x the model's (a misfit the model cannot
    know of); a fault triples it. Against the model the fit finds ~3.9 with a narrow
    interval that misses the fault's own x3; the healthy log's fit (~1.3) widens its
    half-width in ln to about 1.96 sqrt(sd^2 + ln(1.3)^2) > ln(3.9 / 3), so x3 is inside. Without the healthy log the
    interval is the plain one."""
    opts = dict(effects=["friction"], workers=1, bootstrap=3)
    faulty = _log(3.9, 21)
    plain = diagnose(faulty, options=Options(**opts)).json()
    ref = {"name": "cal", "level": None, "margin": None, "logs": ["healthy"],
           "energy": None, "load_current_ratio": None, "healthy_logs": [_log(1.3, 22)]}
    formed = diagnose(faulty, options=Options(**opts, reference=ref)).json()
    s0 = plain["finding"]["effects"][0]["size"]
    s1 = formed["finding"]["effects"][0]["size"]
    assert s0["value"] == s1["value"]                 # values unchanged, interval only
    assert plain["verdict"] == formed["verdict"]
    assert "model_form" not in plain["localisation"]["selection"]
    mf = formed["localisation"]["selection"]["model_form"]
    assert mf["applied"] and mf["healthy_fit"]["friction_scale"] == pytest.approx(1.3, rel=0.1)
    lo0, hi0 = s0["ci95"]
    lo1, hi1 = s1["ci95"]
    assert lo1 < lo0 and hi1 > hi0
    assert not lo0 <= 3.0 <= hi0                     # the plain interval misses x3 ...
    assert lo1 <= 3.0 <= hi1                         # ... the widened one holds it
    # the friction size's term is the healthy fit's own friction size, in quadrature (ln)
    sh = mf["healthy_friction_size"]["friction"]
    assert sh == pytest.approx(1.3, rel=0.1)
    sd0 = math.log(hi0 / lo0) / (2 * 1.96)
    assert math.log(hi1 / lo1) / (2 * 1.96) == pytest.approx(
        math.sqrt(sd0 ** 2 + math.log(sh) ** 2), rel=1e-9)
