"""`bench rig train` / `bench rig classify` on the Cranfield sample (load 40 kgf: healthy
runs 1-4, spalling stage 5 runs 1-2): the label from the file name, leave-runs-out
validation, the JSON of the classes, and every bad input a one-line error that writes
nothing."""

from __future__ import annotations

import io
import json
import lzma
import shutil
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.csv as pacsv
import pytest

from bench.cli import main
from bench.rig import classify as K

SAMPLE = Path(__file__).resolve().parents[1] / "data" / "cranfield_sample"
HEALTHY = SAMPLE / "normal_load40_runs1-4.csv.xz"
SPALL = SAMPLE / "spalling5_load40_runs1-2.csv.xz"


def _table(path: Path) -> pa.Table:
    return pacsv.read_csv(io.BytesIO(lzma.decompress(path.read_bytes())))


def _write(table: pa.Table, path: Path) -> Path:
    pacsv.write_csv(table, path)
    return path


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    d = tmp_path_factory.mktemp("train")
    out = d / "rig.skops"
    cv = d / "cv.json"
    assert main(["rig", "train", str(HEALTHY), str(SPALL), "--actuator", "cranfield",
                 "-o", str(out), "--json", str(cv)]) == 0
    return out, json.loads(cv.read_text())


def test_labels_come_from_the_file_name():
    assert K.table_label("backlash1_runs1-5.csv.xz") == "backlash"
    assert K.table_label("normal_runs5-6") == "normal"
    assert K.table_label("spalling3.csv.xz") == "spalling"
    assert K.table_label("lackLubrication1_runs1-5.csv.xz") == "lackLubrication"
    assert K.table_label("/a/b/normal_load40_runs1-4.csv.xz") == "normal"
    assert K.table_label("12.csv") == ""


def test_validation_leaves_whole_runs_out(model):
    _, cv = model
    b = cv["bench"]
    assert cv["runs"] == 6 and cv["folds"] == 2           # spalling5 has two runs
    assert b["classes"] == ["normal", "spalling"]
    assert sum(map(sum, b["confusion"])) == 30
    for cls, r in b["recall"].items():
        lo, hi = r["rate_95"]
        assert 0.0 <= lo <= r["rate"] <= hi <= 1.0 and r["runs"] >= 2, cls
    assert set(cv["plain_forest"]["recall"]) == {"normal", "spalling"}


def test_folds_never_split_a_run():
    cycles = [c for p in (HEALTHY, SPALL) for c in __import__(
        "bench.rig.cycles", fromlist=["read_cycles"]).read_cycles(p)]
    data = K.Labelled(cycles, [K.table_label(c.source) for c in cycles],
                      [c.source for c in cycles])
    groups = np.asarray(data.groups)
    for test in K.folds_of(data, 5):
        train = np.setdiff1d(np.arange(len(groups)), test)
        assert not set(groups[test]) & set(groups[train])


def test_classify_writes_the_classes_of_every_table(model, tmp_path, capsys):
    path, _ = model
    out = tmp_path / "classes.json"
    assert main(["rig", "classify", str(path), str(SPALL), str(HEALTHY),
                 "--json", str(out)]) == 0
    d = json.loads(out.read_text())
    t = d["tables"]["spalling5_load40_runs1-2"]
    assert t["cycles"] == 10 and sum(t["classes"].values()) == 10
    assert t["label"] == "spalling" and t["seen_in_training"] == 10
    assert len(t["per_cycle"]) == 10 and {"class", "probability"} <= set(t["per_cycle"][0])
    assert d["tables"]["normal_load40_runs1-4"]["cycles"] == 20
    assert "trained on" in capsys.readouterr().out


def test_a_cycle_like_no_class_is_unknown(model, tmp_path):
    """The current 0.5 A higher in every sample (a drive no class has): outside every
    class's spread, unknown rather than the nearest class."""
    path, _ = model
    t = _table(HEALTHY)
    t = t.filter(pc.equal(t["run"], 3))
    cur = pc.add(t["current"], 0.5)
    t = t.set_column(t.schema.get_field_index("current"), "current", cur)
    odd = _write(t, tmp_path / "seized_runs3.csv")
    out = tmp_path / "c.json"
    assert main(["rig", "classify", str(path), str(odd), "--json", str(out)]) == 0
    r = json.loads(out.read_text())["tables"]["seized_runs3"]
    assert r["classes"].get("unknown", 0) == 5
    assert r["unknown_text"] == "unknown (no class within its spread)"


def test_bad_inputs_are_one_line_errors_that_write_nothing(model, tmp_path, capsys):
    path, _ = model
    # a table without a label in its name
    nolabel = shutil.copy(HEALTHY, tmp_path / "1234.csv.xz")
    out = tmp_path / "m.skops"
    assert main(["rig", "train", str(nolabel), str(SPALL), "-o", str(out)]) == 2
    assert "no label in the table's name" in capsys.readouterr().err and not out.exists()
    # a class with one run only
    one = _write(_table(SPALL).filter(pc.equal(_table(SPALL)["run"], 1)),
                 tmp_path / "spalling5_run1.csv")
    assert main(["rig", "train", str(HEALTHY), str(one), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert "class spalling has one run only" in err and len(err.strip().splitlines()) == 1
    # no healthy class
    assert main(["rig", "train", str(SPALL), str(one), "-o", str(out)]) == 2
    assert "no table of the healthy class" in capsys.readouterr().err
    # the model written over an input
    assert main(["rig", "train", str(HEALTHY), str(SPALL), "-o", str(SPALL)]) == 2
    assert "would overwrite it" in capsys.readouterr().err
    # --json over the model
    assert main(["rig", "classify", str(path), str(SPALL), "--json", str(path)]) == 2
    assert "would overwrite it" in capsys.readouterr().err
    assert not out.exists()


def test_a_model_of_another_rig_is_refused(model, tmp_path, capsys):
    """A rig with a 60 mm stroke at twice the speed: its phases and its stroke are not
    the model's."""
    path, _ = model
    t = _table(HEALTHY)
    half = pc.add(pc.multiply(pc.subtract(t["set_point"], 20.0), 0.5), 20.0)
    t = t.set_column(t.schema.get_field_index("set_point"), "set_point", half)
    other = _write(t, tmp_path / "normal_otherrig.csv")
    out = tmp_path / "c.json"
    assert main(["rig", "classify", str(path), str(other), "--json", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert "a model of another rig" in err and "set-point" in err and "\n" not in err
    assert not out.exists()
    from bench.rig import actuators
    another = tmp_path / "another.json"     # a description that exists, not the model's
    shutil.copy(Path(actuators.__file__).with_name("cranfield_rm1605.json"), another)
    assert main(["rig", "classify", str(path), str(HEALTHY), "--actuator",
                 str(another)]) == 2
    assert f"a model of another rig (actuator {another}" in capsys.readouterr().err


class Foreign:
    """A type no bench model holds (a file could carry any such type)."""


def test_a_model_file_is_read_only_when_it_holds_trusted_types(tmp_path, capsys):
    import skops.io as sio
    bad = tmp_path / "bad.skops"
    bad.write_bytes(sio.dumps({"format": "bench-rig-model/1", "x": Foreign()}))
    assert main(["rig", "classify", str(bad), str(HEALTHY)]) == 2
    err = capsys.readouterr().err
    assert "refused" in err or "not a bench rig model" in err
    junk = tmp_path / "junk.skops"
    junk.write_bytes(b"not a zip")
    assert main(["rig", "classify", str(junk), str(HEALTHY)]) == 2
    err = capsys.readouterr().err
    assert "not a bench rig model (not a skops file" in err
    assert "BadZipFile" not in err          # the user's file, not the reader's exception
    plain = tmp_path / "plain.skops"
    plain.write_bytes(sio.dumps({"format": "something else"}))
    assert main(["rig", "classify", str(plain), str(HEALTHY)]) == 2
    assert "not a model written by `bench rig train`" in capsys.readouterr().err


def test_an_actuator_description_that_does_not_exist_is_refused(model, tmp_path, capsys):
    """`--actuator` names a description: one that is neither a file nor a shipped name is
    a one-line error, even for a model that recorded no actuator (it was compared only
    with the model's, so a misspelt name passed unseen)."""
    path, _ = model
    out = tmp_path / "c.json"
    assert main(["rig", "classify", str(path), str(SPALL), "--actuator", "cranfeild",
                 "--json", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error:") and "no such actuator description: cranfeild" in err
    assert len(err.splitlines()) == 1 and not out.exists()
