"""The pairs of the forward selection extend the single the verdict's rules take as the
best: of an LVDT gain and a lead error the one the load cell points to, a plausible alias
in place of a suspect best (docs/gap.md, "Selection")."""

from __future__ import annotations

from types import SimpleNamespace as NS

import pytest

from bench.gap import diagnose as D
from tests.unit.test_gap_lead_or_lvdt import SLOPE, _problem

pytestmark = pytest.mark.unit


def _single(name: str, bic: float, suspect=()) -> NS:
    fit = NS(name=name, effects=(name,), objs=[NS(name=name)], theta=[{}], rss=1.0,
             corr_len=1.0, bic=lambda L, b=bic: b, aic=lambda L, b=bic: b)
    return NS(fit=fit, bic=bic, suspect=list(suspect), heldout_smooth={})


def _select(singles, p, monkeypatch):
    """`diagnose._select` with hand-made single fits: the first effect of every pair it
    asks to fit."""
    asked = []

    def run(tasks, *args, **kwargs):
        if all(len(t[0]) == 1 for t in tasks):
            return list(singles)
        asked.extend(t[0] for t in tasks)
        return [_single("+".join(t[0]), -200.0) for t in tasks]

    monkeypatch.setattr(D, "_run", run)
    monkeypatch.setattr(D, "leaves_gap", lambda *a, **k: True)
    _, _, best, _ = D._select([c.fit.name for c in singles], p, None, None, None,
                              lambda s: None)
    return best, asked


def test_pairs_extend_the_alias_the_load_cell_points_to(monkeypatch):
    """The lead fits best by 2 of BIC, the log's current-on-force slope is the LVDT
    gain's: the pairs are the LVDT gain's (before: the lead's, so an LVDT gain with a
    second effect could only be named a lead plus that effect)."""
    singles = [_single("lead", -100.0), _single("lvdt_gain", -98.0),
               _single("resistance", -50.0)]
    best, asked = _select(singles, _problem(SLOPE, 0.05), monkeypatch)
    assert best.fit.name == "lvdt_gain"
    assert asked and all(a[0] == "lvdt_gain" for a in asked)
    assert ("lvdt_gain", "resistance") in asked and ("lvdt_gain", "lead") in asked


def test_pairs_keep_the_best_where_the_log_cannot_tell(monkeypatch):
    singles = [_single("lead", -100.0), _single("lvdt_gain", -98.0),
               _single("resistance", -50.0)]
    best, asked = _select(singles, _problem(SLOPE, 0.05, load=False), monkeypatch)
    assert best.fit.name == "lead" and all(a[0] == "lead" for a in asked)


def test_pairs_extend_a_plausible_alias_of_a_suspect_best(monkeypatch):
    """A lead 4 % long (suspect) ahead of an LVDT gain by 3 of BIC, no load cell: the
    verdict's rule takes the LVDT gain as the best single, so the pairs are its."""
    singles = [_single("lead", -100.0, suspect=["lead_m x1.04 of the model's"]),
               _single("lvdt_gain", -97.0), _single("resistance", -50.0)]
    best, asked = _select(singles, _problem(SLOPE, 0.05, load=False), monkeypatch)
    assert best.fit.name == "lvdt_gain" and all(a[0] == "lvdt_gain" for a in asked)


def test_other_bests_are_left_alone(monkeypatch):
    singles = [_single("backlash", -100.0), _single("lead", -98.0),
               _single("lvdt_gain", -97.0)]
    best, asked = _select(singles, _problem(SLOPE, 0.05), monkeypatch)
    assert best.fit.name == "backlash" and all(a[0] == "backlash" for a in asked)


def _pair(name: str) -> NS:
    effects = tuple(name.split("+"))
    return NS(fit=NS(name=name, effects=effects, objs=[NS(name=n) for n in effects],
                     theta=[{"x": i} for i in range(len(effects))], rss=1.0))


def test_the_other_alias_of_a_chosen_pair():
    from bench.gap import alias as AL
    assert AL.swap("lead+resistance") == "lvdt_gain+resistance"
    assert AL.swap("backlash+lvdt_gain") == "backlash+lead"
    assert AL.swap("lead") == "lvdt_gain"
    assert AL.swap("lead+lvdt_gain") is None and AL.swap("backlash+kt") is None


def test_a_chosen_alias_pair_is_fitted_with_the_other_alias():
    """Forward selection extended the lead only: the chosen lead+resistance is fitted
    again as lvdt_gain+resistance, from the LVDT gain's single fit and the pair's
    resistance."""
    from bench.gap import alias as AL
    asked = []
    gain = _pair("lvdt_gain")
    gain.fit.theta = [{"lvdt_gain": 1.03}]

    def fit(names, start):
        asked.append((names, start))
        return _pair("+".join(names))

    twin = AL.swapped_pair(_pair("lead+resistance"), [_pair("lead"), gain], fit)
    assert twin.fit.name == "lvdt_gain+resistance"
    assert asked == [(("lvdt_gain", "resistance"), [{"lvdt_gain": 1.03}, {"x": 1}])]
    assert AL.swapped_pair(_pair("lead"), [gain], fit) is None           # a single
    assert AL.swapped_pair(_pair("backlash+kt"), [gain], fit) is None
    assert AL.swapped_pair(_pair("lead+resistance"), [_pair("lead")], fit) is None
    asked.clear()              # already tried beside a best single of its own: not refitted
    tried = _pair("resistance+lvdt_gain")
    assert AL.swapped_pair(_pair("resistance+lead"), [gain], fit, [tried]) is tried
    assert asked == []


def test_the_load_cell_tells_a_pair_from_its_twin():
    """The log's current-on-force slope is the LVDT gain's: the chosen lead+resistance
    gives way to lvdt_gain+resistance; on a log without a load cell it stays, with the
    twin among the ties."""
    from bench.gap import alias as AL
    chosen, twin = _pair("lead+resistance"), _pair("lvdt_gain+resistance")
    got, rec = AL.settle(_problem(SLOPE, 0.05), chosen, [twin])
    assert rec["separated"] and got is twin
    sel: dict = {}
    got, verdict, ranking, ties = D._settle_alias(
        _problem(SLOPE, 0.05, load=False), None, 1.0, chosen, [twin], chosen.fit.name,
        [chosen, twin], [], sel, None)
    assert got is chosen and verdict == "lead+resistance" and ranking == [chosen, twin]
    assert ties == ["lvdt_gain+resistance"] and not sel["lead_or_lvdt_gain"]["separated"]
