"""Monotonic trends of the indexes with degradation on the high-fidelity plant (a few
points of the H2 and H4 sweeps), and the lost motion against the backlash it measures."""

from __future__ import annotations

import numpy as np
import pytest

from bench.hums import indexes as I
from bench.hums import monitor as M
from bench.hums.sweep import degraded
from bench.profiles.catalog import make_profile
from bench.sim.harness import simulate
from plant_rt.params import PlantParams

LEVELS = (0.0, 0.3, 0.6, 1.0)


def _indexes(name: str, noise: bool) -> list[I.Indexes]:
    fit, _ = M.fitted()
    out = []
    for k, d in enumerate(LEVELS):
        real = simulate(make_profile(name), degraded(PlantParams(), d, noise, 40 + k))
        out.append(I.compare(real.measured(), M.nominal_for(real.measured(),
                                                             fit.gain_rad_s_per_m), 2.0))
    return out


@pytest.mark.parametrize("noise", [False, True])
def test_cp_and_mean_error_rise_in_open_loop(noise):
    ix = _indexes("velocity-step", noise)
    cp = np.array([x.cp for x in ix])
    err = np.array([x.mean_error_m for x in ix])
    assert np.all(np.diff(cp) > 0) and np.all(np.diff(err) > 0)
    assert abs(cp[0] - 1) < 0.005 and cp[-1] > 1.03


@pytest.mark.parametrize("noise", [False, True])
def test_ci_falls_in_closed_loop(noise):
    ix = _indexes("sine", noise)
    ci = np.array([x.ci for x in ix])
    cih = np.array([x.ci_harmonic for x in ix])
    assert np.all(np.diff(ci) < 0) and np.all(np.diff(cih) < 0)
    assert ci[-1] < 0.7
    assert abs(cih[0] - 1) < 0.02          # healthy reads ~1 with or without noise
    # the harmonics of the command grow with backlash (H5)
    h3 = np.array([x.harmonics_a[2] for x in ix])
    assert np.all(np.diff(h3) > 0)
    # lost motion: 1 / (cos(alpha) sin(beta)) = 1.416 x backlash, +-5 %
    lm = np.array([x.lost_motion_m for x in ix])
    b = 100e-6 * np.array(LEVELS)
    assert lm[1:] / b[1:] == pytest.approx(np.full(3, 1.416), rel=0.05)
