"""The gap diagnosis' ranking table in words (`bench.gap.summary`): a chosen candidate
below the top rows is shown after an elision that counts the rows left out, and when it
is not the lowest BIC a line says the selection's rules chose it (the table printed
ranks 1-8 and then 10 with no word on rank 9 or on why 10 was chosen)."""

from __future__ import annotations

from bench.gap.summary import _ranking_lines


def _row(rank: int, name: str, bic: float, chosen: bool = False) -> dict:
    return {"rank": rank, "effect": name, "score": {"bic": bic}, "heldout_shrink_pct": 100.0,
            "params": {}, "chosen": chosen}


def _js(rows: list[dict], **sel) -> dict:
    return {"ranking": rows, "localisation": {"selection": sel}}


def test_a_chosen_row_below_the_top_comes_after_an_elision_and_a_reason():
    rows = [_row(k, f"backlash+e{k}", 150.0 + k) for k in range(1, 10)]
    rows.append(_row(10, "backlash", 201.0, chosen=True))
    lines = _ranking_lines(_js(rows, pairs_rejected_as_insignificant=["a", "b"],
                               pairs_rejected_below_floor=["c"],
                               best_single_leaves_significant_heldout_gap=True), top=8)
    assert lines[9].strip() == "... 1 more"
    assert lines[10].lstrip().startswith("10. backlash") and lines[10].endswith("<- chosen")
    assert lines[11].strip().startswith("(chosen by the selection's rules, not by the lowest BIC")
    assert "2 with an added effect insignificant" in lines[11]
    assert "1 with an added effect below the floor" in lines[11]


def test_the_lowest_bic_chosen_needs_no_reason():
    rows = [_row(1, "backlash", 10.0, chosen=True), _row(2, "friction", 12.0)]
    lines = _ranking_lines(_js(rows), top=8)
    assert len(lines) == 3 and lines[1].endswith("<- chosen")


def test_the_text_verdict_says_what_a_friction_factor_is_as_the_html_does():
    """`bench demo` printed friction_levels_scale = 2.3423 [2.1881, 2.5074] on the chosen
    row and "friction x2.38 [2.22, 2.56]" in the verdict, with no word on why the one
    candidate had two friction numbers; the HTML report said it (the verdict's is the
    friction work over the log's motion, fitted / model's), the text did not."""
    from bench.gap.summary import _verdict_line
    how = "friction work over the log's motion, fitted / model's"
    eff = [{"line": "backlash 49.99 um [49.88, 50.1]", "size": {"kind": "lost_motion_m"}},
           {"line": "friction x2.38 [2.22, 2.56] (every level together)",
            "size": {"kind": "factor", "how": how}}]
    js = {"verdict": "backlash+friction_levels",
          "finding": {"line": "backlash ... + friction x2.38", "effects": eff},
          "localisation": {"selection": {}}}
    lines = _verdict_line(js)
    assert lines[2].strip() == (f"friction x2.38 [2.22, 2.56]: {how}. The fitted parameters "
                                "are in the ranking.")
    js["finding"]["effects"] = eff[:1]
    assert len(_verdict_line(js)) == 2
