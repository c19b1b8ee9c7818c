"""bench.rig on synthetic trapezoid cycles: phases with ramps, a localised transient
located where it was put, a level shift named friction-like, not localised."""

from __future__ import annotations

import numpy as np
import pytest

from bench import BenchError
from bench.rig import baseline as B
from bench.rig.cycles import Cycle, phases, ramps
from bench.rig.features import cycle_features, judge


def trapezoid(rng, bump_mm=None, level=0.0, run=1, group=1):
    up = np.linspace(20, 140, 126)[:-1]
    sp = np.r_[up, np.full(75, 140.0), up[::-1] + 0.96]
    pos = sp - 0.05
    d = np.sign(np.r_[np.diff(sp), 0.0])
    cur = 0.8 + 0.15 * d + 0.05 * rng.standard_normal(len(sp)) + level * (d != 0)
    if bump_mm is not None:
        cur += 0.25 * np.exp(-0.5 * ((pos - bump_mm) / 2.0) ** 2) * (d != 0)
    return Cycle(np.arange(len(sp)) * 0.04, sp, pos, cur, 20.0, run, group, "synthetic")


@pytest.fixture(scope="module")
def base():
    rng = np.random.default_rng(7)
    return B.build([trapezoid(rng, run=r, group=g) for r in (1, 2) for g in range(5)])


def test_phases_and_ramps():
    sp = np.r_[np.zeros(5), np.linspace(0, 1, 5) ** 2 * 2, 2 + np.arange(1, 20),
               np.full(6, 21.0)]
    segs = phases(sp)
    assert [s.name for s in segs] == ["dwell_bottom", "out", "dwell_top"]
    r = ramps(sp, segs[1])
    assert r["accel"].stop > r["accel"].start and r["constant"].stop > r["constant"].start


THRESHOLDS = {"localised": 6.0, "level": 1.5, "reversal": 3.0}


def _judged(base, seed: int, **shape):
    """The features and verdict of one generated 20 kgf trapezoid cycle."""
    f = cycle_features(base.for_load(20), trapezoid(np.random.default_rng(seed), **shape))
    return f, judge(f, THRESHOLDS)


def test_localised_transient_is_located(base):
    f, v = _judged(base, 11, bump_mm=95.0)
    assert v.flagged and v.effect == "localised"
    assert abs(f.location_mm - 95.0) < 4.0
    assert abs(f.out_mm - f.in_mm) < 6.0


def test_level_shift_is_friction_like_not_localised(base):
    f, v = _judged(base, 12, level=0.2)
    assert v.flagged and v.effect == "level"
    assert f.scores["localised"] < THRESHOLDS["localised"]


def test_healthy_cycle_is_not_flagged(base):
    assert not _judged(base, 13)[1].flagged


def test_baseline_needs_cycles_and_a_load():
    rng = np.random.default_rng(1)
    with pytest.raises(BenchError, match="at least 3"):
        B.build([trapezoid(rng), trapezoid(rng)])
    c = trapezoid(rng)
    c.load = float("nan")
    with pytest.raises(BenchError, match="no load"):
        B.build([c] * 3)


def test_runs_list():
    from bench.cli.rig import runs_list
    assert runs_list("1,3-4", "--runs") == [1, 3, 4]
    with pytest.raises(BenchError, match="--runs"):
        runs_list("a", "--runs")


def test_a_damaged_or_foreign_baseline_is_a_clear_error(tmp_path):
    p = tmp_path / "b.json"
    p.write_text('{"format": "bench-rig-baseline/1", "sources": [], "loads": [{"load": 1}]}')
    with pytest.raises(BenchError, match="damaged baseline"):
        B.Baseline.load(p)
    p.write_text('{"hello": 1}')
    with pytest.raises(BenchError, match="not a baseline"):
        B.Baseline.load(p)
    # a directory given as the baseline raised IsADirectoryError (exit 1)
    with pytest.raises(BenchError, match="a directory, not a baseline JSON"):
        B.Baseline.load(tmp_path)
    # JSON nested too deep reached the catch-all (RecursionError, exit 1)
    p.write_text("[" * 100_000)
    with pytest.raises(BenchError, match="not a baseline JSON \\(nested too deep to read\\)"):
        B.Baseline.load(p)


def test_thresholds_say_which_run_is_short_of_cycles():
    """Thresholds of one run of 1 cycle and one of 5 said "a baseline needs at least 3
    healthy cycles, got 1" although 6 were given: the 1 is what is left when run 2 is held
    out (leave-one-run-out). Now the message says so, with the cycles per run."""
    from bench.rig import population as P
    rng = np.random.default_rng(3)
    cyc = [trapezoid(rng, run=1, group=0)] + [trapezoid(rng, run=2, group=g)
                                               for g in range(1, 6)]
    with pytest.raises(BenchError) as exc:
        P.calibrate(cyc)
    assert str(exc.value) == (
        "load 20: the thresholds are set leave-one-run-out, and with run 2 held out the "
        "other run(s) (1) have 1 healthy cycle(s), fewer than the 3 a baseline needs "
        "(cycles per run: run 1: 1, run 2: 5)")


def test_a_drive_offset_in_every_phase_is_not_friction(base):
    """The stroke features read the current against the cycle's dwell: an offset of the
    whole cycle's current (the drive's) leaves the level alone, a stroke-only rise not."""
    from bench.rig.features import stroke_signal
    assert stroke_signal(base.for_load(20)) == "current_ref_a"
    c = trapezoid(np.random.default_rng(14))
    c.current_a = c.current_a + 0.1
    assert B.standstill_current(c) == pytest.approx(0.9, abs=0.02)
    f = cycle_features(base.for_load(20), c)
    assert f.scores["level"] < 0.5
    # the index feature reads the phase indexes against the standstill too: a drive
    # offset moves none of them (healthy Cranfield run 1 at -40 kgf steps so)
    assert f.scores["index"] < 3.0
    raw = cycle_features(base.for_load(20), trapezoid(np.random.default_rng(14)))
    assert abs(f.scores["index"] - raw.scores["index"]) < 0.5
    stroke = trapezoid(np.random.default_rng(14))
    stroke.current_a = stroke.current_a + 0.1 * (np.abs(np.gradient(stroke.setpoint_mm)) > 0)
    assert cycle_features(base.for_load(20), stroke).scores["index"] > 5.0


def test_dwell_transient_and_phase_index(base):
    rng = np.random.default_rng(15)
    healthy = cycle_features(base.for_load(20), trapezoid(rng))
    c = trapezoid(rng)
    d = next(s for s in phases(c.setpoint_mm) if s.name == "dwell_top")
    c.current_a[d.start + 10: d.start + 14] -= 0.3
    f = cycle_features(base.for_load(20), c)
    assert f.scores["dwell"] > 2 * healthy.scores["dwell"] and f.scores["dwell"] > 8.0
    v = judge(f, {"localised": 8.0, "level": 1.5, "dwell": 7.0})
    hit, effect = v.flagged, v.effect
    assert hit and effect == "dwell"


def test_a_periodic_effect_is_placed_by_the_localised_scan(base):
    from bench.rig.features import location, verdict
    f = cycle_features(base.for_load(20), trapezoid(np.random.default_rng(16), bump_mm=60.0),
                       lead_mm=5.0)
    thr = {"periodic": 1e-3, "localised": 6.0}
    assert f.scores["localised"] > thr["localised"]
    assert location(f, "periodic", thr) == f.location_mm and abs(f.location_mm - 60.0) < 4.0
    assert location(f, "level", thr) is None
    v = verdict(base, f, thr)
    assert v["effect"] == "periodic" and f"{f.location_mm:.1f} mm" in v["verdict"]
    assert v["location_mm"] == f.location_mm


def test_a_periodic_effect_with_nothing_standing_out_is_not_located(base):
    """The strongest window of a localised scan within its healthy range is
    not a place; a periodic line spread along the stroke is reported as not located."""
    from bench.rig.features import location, verdict
    rng = np.random.default_rng(17)
    c = trapezoid(rng)
    moving = np.sign(np.r_[np.diff(c.setpoint_mm), 0.0]) != 0
    c.current_a = c.current_a + 0.03 * np.sin(2 * np.pi * c.position_mm / 5.0) * moving
    f = cycle_features(base.for_load(20), c, lead_mm=5.0)
    thr = {"periodic": 10.0, "localised": 6.0}
    assert f.scores["periodic"] > thr["periodic"] and f.scores["localised"] < thr["localised"]
    assert location(f, "periodic", thr) is None
    v = verdict(base, f, thr)
    assert v["effect"] == "periodic" and v["location_mm"] is None
    assert "not located" in v["verdict"]


def test_a_lowered_level_is_drag_not_friction(base):
    """Friction raises the current in both directions; a current lowered in
    both directions is named drag lowered."""
    rng = np.random.default_rng(18)
    thr = THRESHOLDS
    low = cycle_features(base.for_load(20), trapezoid(rng, level=-0.2))
    v = judge(low, thr)
    hit, effect = v.flagged, v.effect
    assert hit and effect == "drag"
    from bench.rig.features import verdict
    text = verdict(base, low, thr)["verdict"]
    assert text.startswith("backlash-like") and "drag lowered" in text
    assert "also above threshold: level" not in text          # drag is the level feature
    assert verdict(base, low, thr)["fault"] == "backlash"
    high = cycle_features(base.for_load(20), trapezoid(rng, level=0.2))
    assert judge(high, thr).effect == "level"


def test_a_position_shift_in_every_phase_is_named_an_offset():
    """A play held on one flank by a one-sided load shifts the nut in every phase (docs/decisions.md,
    "A play under a one-sided load"): flagged by a mean position-error index, it was named
    `index`; now, with every phase moved alike, `offset` (backlash-like under a one-sided
    load), each phase's shift in the verdict. A shift of one phase alone stays `index`."""
    from bench.rig.features import verdict
    rng = np.random.default_rng(21)

    def noisy(c):
        c.position_mm = c.position_mm + 0.01 * rng.standard_normal(len(c.position_mm))
        return c
    base = B.build([noisy(trapezoid(rng, run=r, group=g)) for r in (1, 2) for g in range(5)])
    lb = base.for_load(20)
    c = noisy(trapezoid(rng))
    c.position_mm = c.position_mm - 0.1                  # the nut 0.1 mm back everywhere
    f = cycle_features(lb, c)
    assert f.index_at.endswith("position_error_mean") and f.scores["index"] > 20
    assert set(f.position_shift_mm) == {"out", "dwell_top", "in"}
    assert all(abs(v - 0.1) < 0.01 for v in f.position_shift_mm.values())
    v = verdict(base, f, {"index": 10.0})
    assert v["effect"] == "offset" and "out +0.10" in v["verdict"]
    assert "backlash-like under a one-sided load" in v["verdict"]
    assert v["location_mm"] is None
    one = noisy(trapezoid(rng))
    d = next(s for s in phases(one.setpoint_mm) if s.name == "dwell_top")
    one.position_mm[d.start:d.stop] -= 0.1               # the dwell alone
    w = verdict(base, cycle_features(lb, one), {"index": 10.0})
    assert w["effect"] == "index" and "dwell_top +0.10" in w["verdict"]
    assert "backlash" not in w["verdict"]
    # a family's signature is named before a catch-all: the offset (backlash) before a
    # level that moved in one direction only; a level raised in both is friction's
    from bench.rig.naming import level_sign
    named = judge(f, {"index": 10.0, "level": 1e-6}).effect
    assert named == ("offset" if level_sign(f.level_out, f.level_in) == 0 else named)
    assert named in ("offset", "level", "drag")
