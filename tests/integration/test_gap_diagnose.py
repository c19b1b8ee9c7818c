"""Known answers of the gap diagnosis on synthetic logs (4 s, fast plant mode, sensor
noise on, a small candidate set to keep the suite fast): each effect alone is found,
an effect outside the library is "unexplained", a clean log gets no attribution, and
logs without a set-point or with too little motion are refused with a clear error."""

from __future__ import annotations

import numpy as np
import pytest

from bench import BenchError
from bench.gap.diagnose import Options, diagnose
from bench.gap.resim import FAST
from bench.gap.result_json import chosen_entry
from bench.profiles.maneuvers import compact
from bench.signals.trace import Trace
from bench.sim.harness import simulate
from plant_rt.params import PlantParams

SET = ["backlash", "friction", "kt", "sensor_delay", "lvdt_lag", "encoder_gain"]
OPTS = Options(effects=SET, workers=1, bootstrap=3)


_CACHE: dict = {}


def diagnosed(name: str, tr_fn) -> dict:
    """Diagnose once per module (the suite stays fast)."""
    if name not in _CACHE:
        _CACHE[name] = diagnose(tr_fn(), options=OPTS).json()
    return _CACHE[name]


def log(extra=None, seed=11) -> Trace:
    p = PlantParams().with_dict({**FAST, "sensors.noise": True, "sensors.noise_seed": seed,
                                 **(extra or {})})
    return simulate(compact(), p).measured()


def lag(tr: Trace, tau_s: float) -> Trace:
    a = np.exp(-tr.dt / tau_s)
    y = tr["position_m"].copy()
    for i in range(1, len(y)):
        y[i] = a * y[i - 1] + (1 - a) * tr["position_m"][i]
    tr.columns["position_m"] = y
    return tr


@pytest.mark.parametrize("name, extra, param, value, rtol", [
    ("backlash", {"effects.backlash_m": 40e-6}, "backlash_m", 40e-6, 0.1),
    ("friction", {"effects.friction_scale": 6.0}, "friction_scale", 6.0, 0.25),
    ("kt", {"motor.kt_nm_per_a": 1.3}, "kt_nm_per_a", 1.3, 0.05),
    ("sensor_delay", {"effects.sensor_delay_s": 0.002}, "sensor_delay_s", 0.002, 0.01),
    ("encoder_gain", {"sensors.encoder_gain": 1.04}, "encoder_gain", 1.04, 0.01),
    ("lvdt_lag", None, "lvdt_lag_s", 0.005, 0.1),
])
def test_each_effect_alone_is_found(name, extra, param, value, rtol):
    def make() -> Trace:
        tr = log(extra)
        return lag(tr, 0.005) if name == "lvdt_lag" else tr
    js = diagnosed(name, make)
    assert js["verdict"] == name, js["localisation"].get("selection")
    top = chosen_entry(js)
    assert top["effect"] == name
    got = top["params"][param]
    assert got["value"] == pytest.approx(value, rel=rtol)
    lo, hi = got["ci95"]
    assert lo <= got["value"] <= hi
    assert top["heldout_shrink_pct"] > 70.0
    assert set(js) == {"localisation", "ranking", "verdict", "finding"}
    assert set(top) == {"rank", "effect", "families", "chosen", "params", "gap_before",
                        "gap_after", "heldout_shrink_pct", "score", "suspect", "at_bound"}
    bics = [c["score"]["bic"] for c in js["ranking"]]
    assert bics == sorted(bics)                    # the table is in the order it names


def test_backlash_lives_in_the_screw_path_as_lost_motion():
    js = diagnosed("backlash", lambda: log({"effects.backlash_m": 40e-6}))
    paths = js["localisation"]["paths"]
    assert max(("drive", "mechanics", "screw", "sensors"),
               key=lambda k: paths[k]["share"]) == "screw"
    # the plant's backlash is along the contact normal: axial lost motion b / (cos a sin b)
    g = np.cos(np.radians(3.04)) * np.sin(np.radians(45.0))
    assert paths["screw"]["lost_motion_m"] == pytest.approx(40e-6 / g, rel=0.1)
    clean = diagnosed("clean", lambda: log(seed=5))["localisation"]["paths"]["screw"]
    # the screw path's kinematics are rigid: under the maneuver's +-2 kN load the nominal
    # contacts' own compliance (about 1 nm/N) is left in it, a few um at most
    assert abs(clean["lost_motion_m"]) < 4e-6


def test_load_cell_separates_a_soft_screw_from_backlash():
    """Under the maneuver's logged sine load a soft screw deflects in proportion to the
    load while backlash is a jump when the load changes sign: the two are told apart
    (without the load both are dead-zone-like lost motion of the same size)."""
    opts = Options(effects=["backlash", "stiffness"], workers=1, bootstrap=3)
    js = diagnose(log({"screw.contact_stiffness_n_per_m": 2e6}), options=opts).json()
    assert js["verdict"] == "stiffness"
    assert js["localisation"]["selection"]["indistinguishable_from_chosen"] == []
    k = chosen_entry(js)["params"]["contact_stiffness_n_per_m"]["value"]
    assert k == pytest.approx(2e6, rel=0.1)
    bic = {r["effect"]: r["score"]["bic"] for r in js["ranking"]}
    assert bic["backlash"] - bic["stiffness"] > 100.0
    assert "replayed from the load cell" in js["localisation"]["model"]["load"]


def test_effect_outside_the_library_is_unexplained():
    """A position-periodic current-sensor error (6 per motor turn) is in no candidate."""
    tr = log()
    tr.columns["current_a"] = tr["current_a"] + 0.4 * np.sin(6 * tr["motor_angle_rad"])
    js = diagnose(tr, options=OPTS).json()
    assert js["verdict"] == "unexplained"
    assert js["localisation"]["signals"]["current_a"]["share"] > 0.5
    assert js["ranking"]                      # candidates were still fitted and ranked


def test_clean_log_gets_no_attribution():
    js = diagnosed("clean", lambda: log(seed=5))
    assert js["verdict"] == "none"
    assert js["ranking"] == []
    assert js["localisation"]["significance"]["significant"] is False


def test_log_without_setpoint_is_refused():
    tr = log()
    del tr.columns["setpoint_position_m"]
    del tr.columns["setpoint_speed_rad_s"]
    with pytest.raises(BenchError, match="no set-point.*setpoint_position_m"):
        diagnose(tr, options=OPTS)


def test_log_with_too_little_motion_is_refused():
    p = PlantParams().with_dict({**FAST, "sensors.noise": True})
    prof = compact()
    from bench.profiles.catalog import Profile
    still = Profile("still", prof.mode, 1.0, lambda t: 1e-6 * np.sin(t), prof.speed)
    with pytest.raises(BenchError, match="too little motion.*travelled"):
        diagnose(simulate(still, p).measured(), options=OPTS)


def test_missing_sensor_is_named():
    tr = log()
    del tr.columns["motor_angle_rad"]
    with pytest.raises(BenchError, match="motor_angle_rad"):
        diagnose(tr, options=OPTS)


def test_monitor_model_skips_effects_it_cannot_represent():
    pytest.importorskip("bench.hums.monitor")
    opts = Options(model="monitor", effects=["backlash", "kt", "lvdt_lag"], workers=1,
                   bootstrap=2, fit_always=True)
    js = diagnose(log({"motor.kt_nm_per_a": 1.3}), options=opts).json()
    m = js["localisation"]["model"]
    assert m["name"] == "monitor" and m["effects_not_representable"] == ["backlash"]
    assert {r["effect"] for r in js["ranking"]} >= {"kt", "lvdt_lag"}
    assert "backlash" not in {r["effect"] for r in js["ranking"]}


def test_unknown_model_is_a_clear_error():
    with pytest.raises(BenchError, match="unknown model 'sim'"):
        diagnose(log(), options=Options(model="sim", workers=1))


def test_lost_frames_are_interpolated_and_too_many_refused():
    from bench.gap.problem import fill_gaps
    tr = log()
    tr.columns["position_m"][100:103] = np.nan          # three lost SYNCs
    tr.columns["mode"][100:103] = np.nan
    out = fill_gaps(tr)
    assert np.isfinite(out["position_m"]).all() and out["mode"][101] == 1.0
    tr.columns["current_a"][:500] = np.nan
    with pytest.raises(BenchError, match="of current_a is missing"):
        fill_gaps(tr)
    tr = log()
    tr.columns["run"] = np.r_[np.ones(2000), 2 * np.ones(len(tr) - 2000)]
    with pytest.raises(BenchError, match="holds 2 runs"):
        diagnose(tr, options=OPTS)
