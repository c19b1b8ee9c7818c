"""The diagnosis's re-simulations are kept by value and its fits scheduled on workers
without changing a result: a repeated parameter set is simulated once and returns the same
columns, which no caller can change for another; a run of the whole log goes on from the
fit part's state with the columns of a run from the start; the nominal run is kept per
length and the cache drops the least recently used; tasks come back in their order wherever
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


def test_a_whole_log_run_goes_on_from_the_fit_part_with_the_columns_of_a_fresh_run(
        monkeypatch):
    """A fit's optimum on the fit part, then on the whole log (the held-out energies): the
    second run starts from the first's state before its last period and simulates the rest
    only, with the columns of a run from the start (loop delays too)."""
    p = _problem()
    real = R.closed_loop
    starts = []

    def counted(*a, **k):
        starts.append(0 if k.get("resume") is None else k["resume"].k)
        return real(*a, **k)
    monkeypatch.setattr(R, "closed_loop", counted)
    for name, th in (("friction", {"friction_scale": 2.0}),
                     ("encoder_delay", {"encoder_delay_s": 0.003})):
        eff = [E.get(name)]
        starts.clear()
        part = p.simulate(eff, [th], p.n_fit)
        whole = p.simulate(eff, [th])
        assert starts == [0, p.n_fit - 1]
        params, delays = p.params_for(eff, [th]), p.loop_delays(eff, [th])
        fresh = p.signals(real(params, p.drive, None, delays=delays))
        for s in R.SIGNALS:
            np.testing.assert_array_equal(whole[s], fresh[s], err_msg=f"{name} {s}")
            np.testing.assert_array_equal(part[s], fresh[s][:p.n_fit], err_msg=f"{name} {s}")


def _count_loops(monkeypatch) -> list[int]:
    """The closed-loop re-simulations run from here on, one entry each."""
    real = R.closed_loop
    runs: list[int] = []

    def counted(*a, **k):
        runs.append(1)
        return real(*a, **k)
    monkeypatch.setattr(R, "closed_loop", counted)
    return runs


def test_the_nominal_run_is_kept_for_the_fit_part_and_the_whole_log(monkeypatch):
    """An effect on the log alone asks for the nominal run of the fit part and of the whole
    log in turn: each is simulated once."""
    p = _problem()
    p._cache.clear()
    runs = _count_loops(monkeypatch)
    eff = [E.get("current_offset_log")]
    th = [{q.name: q.from_unit(0.7) for q in eff[0].params}]
    for _ in range(3):
        p.simulate(eff, th, p.n_fit)
        p.simulate(eff, th)
    assert len(runs) == 2


def test_a_run_in_use_outlives_older_ones_in_the_cache(monkeypatch):
    """The cache drops the least recently used run: one asked for again and again (a
    single's optimum, where each of its pairs starts) stays while others come and go."""
    p = _problem()
    eff = [E.get("friction")]
    keep = [{"friction_scale": 3.0}]
    p.simulate(eff, keep, 50)
    runs = _count_loops(monkeypatch)
    for k in range(2 * P.LOOP_CACHE):
        p.simulate(eff, [{"friction_scale": 1.0 + 0.01 * k}], 50)
        p.simulate(eff, keep, 50)
    assert len(runs) == 2 * P.LOOP_CACHE            # the others only
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
