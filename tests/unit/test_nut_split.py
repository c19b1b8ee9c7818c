"""Where the Coulomb friction acts: against a model whose friction split is declared
unknown, the effects that show it fit the share of the model's nut friction F_s that
stays at the nut (`bench.gap.library.nut_split`); against a model whose split is known
(the default, the bench's own plant) they are fitted exactly as before (docs/gap.md,
"Where the friction acts")."""

import math

import numpy as np
import pytest

from bench import BenchError
from bench.gap import effects as E
from bench.gap import problem as P
from bench.gap.diagnose import Options, diagnose
from bench.gap.fit import fit, for_problem, shared_once
from bench.gap.library import NUT_SHARE, nut_split, with_nut_share
from bench.profiles.maneuvers import excitation
from bench.sim.harness import simulate
from plant_rt.model import static_friction
from plant_rt.params import PlantParams

SHOWN = ("stiffness", "preload", "backlash", "friction")


@pytest.mark.parametrize("share", [0.0, 0.3, 1.0])
def test_the_split_keeps_the_motor_side_coulomb_torque(share):
    base = PlantParams().with_dict({"screw.lead_m": 4e-3, "screw.nut_static_friction_n": 300.0})
    moved = base.with_dict(nut_split(share, base))
    assert moved.screw.nut_static_friction_n == pytest.approx(share * 300.0)

    def at_motor(q: PlantParams) -> float:    # C_s + F_s p / 2 pi, eq. 5.14 and 5.31
        return static_friction(q) + q.screw.nut_static_friction_n * q.screw.lead_m / (2 * math.pi)
    assert at_motor(moved) == pytest.approx(at_motor(base), rel=1e-12)


@pytest.mark.parametrize("name", SHOWN)
def test_the_share_is_fitted_only_when_the_split_is_unknown(name):
    base = PlantParams()
    eff = E.get(name)
    own = eff.params[0].name
    # registered (and fitted on a model whose split is known) with its own parameter only
    assert [p.name for p in eff.params] == [own]
    known = P.Problem(base, None, {}, {}, 0, 1e-3)            # type: ignore[arg-type]
    assert [p.name for p in for_problem(known, [name])[0].params] == [own]
    assert eff.start_points(base) == E.get(name).start_points(base)
    # against a model whose split is unknown: the share too, nominal 1, from both ends
    unknown = P.Problem(base, None, {}, {}, 0, 1e-3, friction_split="unknown")  # type: ignore[arg-type]
    sh = for_problem(unknown, [name])[0]
    assert [p.name for p in sh.params] == [own, NUT_SHARE.name]
    nom = sh.nominal(base)
    assert nom[NUT_SHARE.name] == 1.0
    assert list(sh.plant_overrides(nom, base)) == list(eff.plant_overrides(nom, base))
    pts = sh.start_points(base)
    assert {sp[NUT_SHARE.name] for sp in pts} == {0.0, 1.0}
    assert [sp[own] for sp in pts if sp[NUT_SHARE.name] == 0.0] == \
        [sp[own] for sp in eff.start_points(base)]
    # a fitted share re-simulates from the effect's name (the report re-resolves it)
    th = {own: nom[own], NUT_SHARE.name: 0.25}
    assert eff.plant_overrides(th, base) == sh.plant_overrides(th, base)
    assert eff.plant_overrides(th, base)["screw.nut_static_friction_n"] == \
        pytest.approx(0.25 * base.screw.nut_static_friction_n)
    # effects that do not show the split are left alone
    assert with_nut_share(E.get("viscous")) is E.get("viscous")


def test_a_compliant_nut_with_its_friction_at_the_screw_is_fitted_as_stiffness():
    """A log of the bench's plant with a soft contact (k* 3e6 N/m) and all of the nut's
    friction at the screw: against the model with its split declared unknown, `stiffness`
    fits the share near 0 and reaches a cost that the model's split (known, the share
    held at 1) does not reach (the nut's friction would deflect the contacts)."""
    nominal = PlantParams()
    truth = nominal.with_dict({"screw.contact_stiffness_n_per_m": 3e6,
                               **nut_split(0.0, nominal),
                               "sensors.noise": True, "sensors.noise_seed": 11})
    log = simulate(excitation(2.0), truth)
    fits = {}
    for split in ("unknown", "model"):
        p = P.build(log.measured(), nominal, 0.3, bootstrap=2, model_floor=False,
                    friction_split=split)
        eff = for_problem(p, ["stiffness"])[0]
        fits[split] = fit(p, ["stiffness"], [eff.nominal(p.base)], max_nfev=40)
    got = fits["unknown"].theta[0]
    assert got[NUT_SHARE.name] < 0.2
    assert got["contact_stiffness_n_per_m"] == pytest.approx(3e6, rel=0.25)
    assert NUT_SHARE.name not in fits["model"].theta[0]
    assert fits["unknown"].rss < 0.5 * fits["model"].rss
    assert np.isfinite(fits["unknown"].rss)


def test_a_pair_fits_the_share_once_with_the_last_effect():
    effs = shared_once([with_nut_share(E.get("friction")), with_nut_share(E.get("stiffness"))])
    assert [p.name for p in effs[0].params] == ["friction_scale"]
    assert [p.name for p in effs[1].params] == ["contact_stiffness_n_per_m", NUT_SHARE.name]
    assert all(NUT_SHARE.name not in sp for sp in effs[0].start_points(PlantParams()))
    assert [p.name for p in shared_once([E.get("viscous"),
                                         with_nut_share(E.get("friction"))])[1].params] \
        == ["friction_scale", NUT_SHARE.name]


def test_a_friction_split_other_than_model_or_unknown_is_refused():
    log = simulate(excitation(0.2), PlantParams())
    with pytest.raises(BenchError, match="friction split 'nut'"):
        diagnose(log, options=Options(friction_split="nut", workers=1))


def test_the_workers_problem_keeps_the_declared_split():
    """`bench gap` fits in worker processes on a stripped copy of the problem; the copy
    used to be rebuilt field by field and dropped the declaration (the share was then
    never fitted with --workers 2)."""
    from dataclasses import fields

    from bench.gap.diagnose import _strip
    p = P.Problem(PlantParams(), None, {"x": np.zeros(3)}, {"x": 1.0}, 2, 1e-3,  # type: ignore[arg-type]
                  info={"big": 1}, model="monitor", friction_split="unknown")
    q = _strip(p)
    assert q.info == {} and q.holdout is None and q._cache == {}
    for f in fields(P.Problem):
        if f.name not in ("info", "holdout", "_cache"):   # the nominal run's memo stays here
            assert getattr(q, f.name) is getattr(p, f.name), f.name


def test_gap_takes_the_split_from_the_flag_then_the_calibration(tmp_path):
    import argparse
    import json

    from bench.cli.gap import friction_split
    cal = tmp_path / "cal.json"

    def split(flag, doc):
        cal.write_text(json.dumps(doc))
        ns = argparse.Namespace(friction_split=flag, nominal=str(cal))
        return friction_split(ns, json.loads(cal.read_text()))

    assert friction_split(argparse.Namespace(friction_split=None, nominal=None), None) == "model"
    assert split(None, {"params": {}, "friction_split": "unknown"}) == "unknown"
    assert split("model", {"params": {}, "friction_split": "unknown"}) == "model"
    assert split(None, {"params": {}}) == "model"   # written before the declaration existed
    with pytest.raises(BenchError, match="friction_split 'nut' is not one of model, unknown"):
        split(None, {"params": {}, "friction_split": "nut"})


def test_bounds_moved_to_the_model_keep_the_share():
    """`_Single.for_model` moves the own parameter's bounds and keeps any other parameter
    (the share), so a scaled effect that fits the share still fits it."""
    eff = with_nut_share(E.get("stiffness"))
    scaled = type(eff)()
    scaled.params = eff.params
    scaled.scales_with_model = True          # as lead, kt, inertia, resistance
    base = PlantParams().with_dict({"screw.contact_stiffness_n_per_m": 1e9})   # above 1.5e8
    moved = scaled.for_model(base)
    assert moved is not scaled
    assert [p.name for p in moved.params] == ["contact_stiffness_n_per_m", NUT_SHARE.name]
    assert moved.params[0].hi > eff.params[0].hi
