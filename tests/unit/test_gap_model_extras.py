"""The LVDT conditioning as a declared sensor property (`sensors.lvdt_time_constant_s`),
what a loaded healthy log calibrates (`bench.gap.calibrate.default_names`) and the pair
rule judged against a calibration."""

import math

import numpy as np
import pytest

from bench.gap import calibrate as C
from bench.gap import resim as R
from bench.signals.trace import Trace
from plant_rt import kernel as K
from plant_rt.model import Plant, param_vector
from plant_rt.params import ParameterError, PlantParams

FAST = PlantParams().with_dict({**R.FAST, "sensors.noise": False})


def _run(plant: Plant, n: int) -> tuple[np.ndarray, np.ndarray]:
    rows, nut = [], []
    for k in range(n):
        rows.append(plant.measure()[:4])
        nut.append(0.5 * (plant.x[K.X1] + plant.x[K.X2]))
        plant.step(4.0 * math.sin(k / 15.0))
    return np.array(rows), np.array(nut)


def test_default_is_the_eq_5_1_filter_bit_for_bit():
    """0 (default) keeps the thesis' second-order LVDT: the same readings as the code
    before the option existed (values recorded on that code, same run)."""
    assert PlantParams().sensors.lvdt_time_constant_s == 0.0
    assert param_vector(FAST)[K.P_LTAU] == 0.0
    y, _ = _run(Plant(FAST), 60)
    assert float(y[:, 3].sum()) == pytest.approx(0.004442797935976845, rel=1e-12)
    assert float(y[-1, 3]) == pytest.approx(0.00022802219366934505, rel=1e-12)
    assert float(y[:, 1].sum()) == pytest.approx(1184.413450093194, rel=1e-12)


def test_first_order_lag_of_the_nut():
    """tau > 0: the LVDT is a first-order lag of the nut position (the filter's rate
    state stays 0), as the offline sensor path (`resim.lvdt_dynamics`) models it."""
    tau = 2e-3
    pp = FAST.with_dict({"sensors.lvdt_time_constant_s": tau})
    plant = Plant(pp)
    y, nut = _run(plant, 120)
    assert plant.x[K.LYD] == 0.0
    lag = R.first_order(nut, pp.sim.sync_period_s, tau)
    travel = float(np.ptp(nut))
    assert travel > 1e-5
    # the kernel integrates within the period, the offline path holds each sample: half a
    # period apart at most
    assert np.max(np.abs(y[1:, 3] - lag[:-1])) < 0.1 * travel
    np.testing.assert_array_equal(R.lvdt_dynamics(nut, 1e-3, pp), lag)
    assert np.max(np.abs(y[:, 3] - nut)) > 0.02 * travel     # it does lag
    with pytest.raises(ParameterError):
        PlantParams().with_dict({"sensors.lvdt_time_constant_s": -1e-3})


def test_default_names_add_what_the_log_identifies():
    n = 50
    cols = {"t_s": np.arange(n) * 1e-3, "load_force_n": np.full(n, 10.0)}
    assert C.default_names(Trace(cols, {})) == C.DEFAULT + ("motor.viscous_friction_nm_s",)
    cols["load_force_n"] = 2000.0 * np.sin(np.arange(n))
    loaded = C.default_names(Trace(cols, {}))
    assert loaded[-2:] == ("screw.contact_stiffness_n_per_m", "screw.reaction_lever_m")
    assert "screw.contact_stiffness_n_per_m" not in C.DEFAULT
    assert set(loaded) <= set(C.UNCERTAIN)


def test_pair_rule_is_judged_against_the_calibration():
    """A best single whose held-out residual is below the calibration's held-out level x
    margin leaves no significant gap, so no pair replaces it (with the default threshold
    alone the pair would)."""
    from types import SimpleNamespace as NS

    from bench.gap import diagnose as D

    sig = dict.fromkeys(R.SIGNALS, 1.0)
    single = NS(fit=NS(name="lvdt_offset", effects=("lvdt_offset",)), bic=0.0,
                heldout_excess=1.0, heldout_smooth={**sig, "position_m": 3.0})
    pair = NS(fit=NS(name="lvdt_offset+preload", effects=("lvdt_offset", "preload")),
              bic=-50.0, heldout_excess=0.2, heldout_smooth=sig, faint=[])
    p = NS(n=10000, n_fit=5000, info={})
    ref = {"level": dict.fromkeys(R.SIGNALS, 2.5), "margin": dict.fromkeys(R.SIGNALS, 1.5)}
    args = ([single], [pair], single, p, None, 100.0, True, {})
    assert D._choose(*args)[0] is pair
    assert D._choose(*args, ref)[0] is single
