"""`bench rig study` names its fault tables by stage only where they are one family's
numbered stages, the number taken from the family word (spalling5_load40_runs1-2 is
stage 5, not 2), and its page is the reports' styled page."""

from __future__ import annotations

from bench.rig.cycles import stage_number
from bench.rig.study import Study, condition_key


def _study(*conds: str) -> Study:
    return Study(None, {}, [], {c: {} for c in ("normal_runs1-4", *conds)}, "normal_runs1-4")


def test_stage_is_the_number_of_the_family_word():
    assert stage_number("spalling8") == 8
    assert stage_number("spalling5_load40_runs1-2") == 5
    assert stage_number("backlash1_runs1-5") == 1
    assert stage_number("normal_runs1-4") is None
    from bench.rig.cycles import condition_family
    assert condition_family("spalling5_load40_runs1-2") == "spalling#_load40_runs1-2"
    assert condition_family("spalling5") == condition_family("spalling7")


def test_labels_and_order():
    one = _study("spalling5_load40_runs1-2")
    assert one.condition_label("spalling5_load40_runs1-2") == "5"
    assert getattr(one, "stage_header", "stage") == "stage"
    stages = _study(*(f"spalling{k}" for k in (3, 1, 2)))
    assert stages.fault_conditions == ["spalling1", "spalling2", "spalling3"]
    assert [stages.condition_label(c) for c in stages.fault_conditions] == ["1", "2", "3"]
    mixed = _study("spalling1", "backlash1_runs1-5", "lackLubrication1_runs1-5")
    assert mixed.condition_label("backlash1_runs1-5") == "backlash1_runs1-5"
    assert getattr(mixed, "stage_header", "condition") == "condition"
    assert sorted(mixed.fault_conditions, key=condition_key) == mixed.fault_conditions


def test_every_rig_action_has_a_description():
    """`bench rig ACTION --help` says what the action does, not only its usage."""
    import argparse

    from bench.cli import rig
    top = argparse.ArgumentParser()
    rig.add_subparser(top.add_subparsers())
    actions = next(a for a in top._actions if isinstance(a, argparse._SubParsersAction))
    sub = next(a for a in actions.choices["rig"]._actions
               if isinstance(a, argparse._SubParsersAction))
    assert set(sub.choices) == {"baseline", "assess", "study", "inject", "train", "classify"}
    for name, p in sub.choices.items():
        assert p.description and len(p.description) > 80, name
        assert p.description.split()[0] in p.format_help(), name
