"""`bench calibrate --controller`: one option whose values depend on the path (the thesis
plant: bench-ecu, fitted-cascade, measured-current; --actuator: auto, fit-gains,
measured-current); a value the path does not take is a one-line error before any fit."""

from __future__ import annotations

import pytest

from bench.cli import main


@pytest.mark.parametrize(("extra", "value", "takes"), [
    ((), "fit-gains", "for the thesis plant (without --actuator): choose bench-ecu, "
                      "fitted-cascade, measured-current"),
    ((), "auto", "for the thesis plant"),
    (("--actuator", "cranfield"), "fitted-cascade",
     "with --actuator (the generic model): choose auto, fit-gains, measured-current"),
    (("--actuator", "cranfield"), "bench-ecu", "with --actuator"),
])
def test_a_value_of_the_other_path_is_one_line(tmp_path, capsys, extra, value, takes):
    rc = main(["calibrate", str(tmp_path / "missing.npz"), *extra, "--controller", value,
               "-o", str(tmp_path / "c.json")])
    assert rc != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"error: --controller {value} is not "
                                               "available ") and takes in err[0]
    assert not (tmp_path / "c.json").exists()


def test_the_friction_split_is_refused_on_the_generic_model_in_one_line(tmp_path, capsys):
    rc = main(["calibrate", str(tmp_path / "missing.npz"), "--actuator", "cranfield",
               "--friction-split", "unknown", "-o", str(tmp_path / "c.json")])
    assert rc != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: --friction-split is for the thesis")
    assert not (tmp_path / "c.json").exists()
