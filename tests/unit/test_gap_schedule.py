"""The diagnosis's re-simulations are kept by value and its fits scheduled on workers
without changing a result: a repeated parameter set is simulated once and returns the same
columns, which no caller can change for another; tasks come back in their order wherever
they ran, the costliest submitted first, the cheapest fitted here while the workers start."""

from __future__ import annotations

import numpy as np

from bench.gap import effects as E
from bench.gap import problem as P
from bench.gap import resim as R
from bench.gap import schedule as S
from bench.profiles.maneuvers import excitation
from bench.sim.harness import simulate
from plant_rt.params import PlantParams

FAST = PlantParams().with_dict(R.FAST)


def _problem() -> P.Problem:
    tr = simulate(excitation(1.0, load_n=0.0), FAST.with_dict({"sensors.noise": True}))
    return P.build(tr.measured(), PlantParams(), 0.5, bootstrap=2, model_floor=False)


def test_a_repeated_parameter_set_is_simulated_once_and_stays_unchanged(monkeypatch):
    p = _problem()
    runs = []
    real = R.closed_loop

    def counted(*a, **k):
        runs.append(1)
        return real(*a, **k)
    monkeypatch.setattr(R, "closed_loop", counted)
    eff = [E.get("backlash")]
    th = [{"backlash_m": 20e-6}]
    first = p.simulate(eff, th, p.n_fit)
    kept = {s: v.copy() for s, v in first.items()}
    first["position_m"][:] = 0.0                 # a caller scribbling on its columns
    again = p.simulate(eff, [{"backlash_m": 20e-6}], p.n_fit)
    assert len(runs) == 1
    for s in kept:
        np.testing.assert_array_equal(again[s], kept[s], err_msg=s)
    other = p.simulate(eff, [{"backlash_m": 20e-6 * (1 + 1e-15)}], p.n_fit)   # another value
    longer = p.simulate(eff, th)                                              # another length
    assert len(runs) == 3
    assert len(longer["position_m"]) == p.n and len(other["position_m"]) == p.n_fit
    direct = p.signals(real(p.params_for(eff, th), p.drive, p.n_fit))
    for s in kept:
        np.testing.assert_array_equal(again[s], direct[s], err_msg=s)


def test_a_changed_drive_is_simulated_anew():
    p = _problem()
    eff, th = [E.get("friction")], [{"friction_scale": 1.5}]
    a = p.simulate(eff, th)
    p.drive = P.R.Drive(p.drive.t, p.drive.sp_pos + 1e-3, p.drive.sp_spd, p.drive.mode,
                        p.drive.demand, p.drive.x0_m, p.drive.x0_true_m)
    b = p.simulate(eff, th)
    assert not np.array_equal(a["position_m"], b["position_m"])


def test_the_cache_is_bounded():
    p = _problem()
    eff = [E.get("friction")]
    for k in range(P.LOOP_CACHE + 5):
        p.simulate(eff, [{"friction_scale": 1.0 + 0.01 * k}], 50)
    assert len(p._cache["loops"]) == P.LOOP_CACHE


class _Future:
    def __init__(self, value):
        self.value = value

    def result(self):
        return self.value


class _Pool:
    """A pool whose workers are ready after `late` readiness checks."""

    def __init__(self, late: int) -> None:
        self.late = late
        self.submitted: list[tuple[str, ...]] = []

    def ready(self) -> bool:
        self.late -= 1
        return self.late < 0

    def started(self):
        return self

    def share(self, obj):
        return obj

    def submit(self, fn, p, h, names, start):
        self.submitted.append(names)
        return _Future(fn(p, h, names, start))


def test_tasks_come_back_in_order_costliest_submitted_first_cheapest_here():
    p = _problem()
    names = ["current_gain_log", "friction", "stribeck", "friction_apart", "lvdt_offset"]
    tasks = [((n,), None) for n in names]
    where: dict[str, str] = {}

    def evaluate(p, h, names, start):
        where.setdefault(names[0], "here")
        return names[0]

    def task(p, h, names, start):
        where[names[0]] = "pool"
        return names[0]
    pool = _Pool(late=2)
    out = S.on_pool(task, evaluate, lambda q: q, tasks, p, None, pool)
    assert out == names
    # the two cheapest (a log-side effect, then the order of the library) ran here
    assert where["current_gain_log"] == "here" and where["lvdt_offset"] == "here"
    assert pool.submitted == [("friction_apart",), ("stribeck",), ("friction",)]
    assert S.weight(("friction_apart",), p) > S.weight(("stribeck",), p) > \
        S.weight(("friction",), p) > S.weight(("current_gain_log",), p)
