"""A loop that oscillates by itself (`bench.gap.limitcycle`): the line statistic on
synthetic residuals, and on the independent actuator under the bench's ECU with a
4-period sensor delay, which makes its speed loop oscillate (docs/gap.md, "The verdict in words")."""

import numpy as np
import pytest

from bench.gap import limitcycle as LC
from bench.gap import problem as P
from bench.gap.blind import Case, Truth
from bench.gap.indiebench import datasheet_model, generate

DT = 1e-3


def test_one_line_holding_the_residual_is_a_limit_cycle_and_noise_is_not():
    rng = np.random.default_rng(3)
    t = np.arange(5000) * DT
    noise = [rng.normal(0.0, 0.05, t.size) for _ in range(3)]
    osc = LC.line(0.5 * np.sin(2 * np.pi * 23.4 * t) + noise[0], DT, noise[1:])
    assert osc["freq_hz"] == pytest.approx(23.4, abs=osc["bin_hz"])
    assert osc["line_share"] > 0.9 and osc["psd_ratio"] > 1e3 and LC.oscillates(osc)
    calm = LC.line(noise[0], DT, noise[1:])
    assert calm["line_share"] < 0.2 and not LC.oscillates(calm)
    # a slow motion (below F_LO_HZ, the set-point's own) is not looked at
    slow = LC.line(0.5 * np.sin(2 * np.pi * 2.0 * t) + noise[0], DT, noise[1:])
    assert not LC.oscillates(slow)


@pytest.fixture(scope="module")
def delayed():
    model = datasheet_model()
    out = {}
    for name, truths in (("delay", [{"sensor_delay_periods": 4.0}]), ("nominal", [])):
        case = Case(0, "single" if truths else "nominal",
                    [Truth("sensor_delay", t) for t in truths], 4242)
        log = generate(case, True, 4.0, "ecu")
        out[name] = P.build(log.measured(), model, 0.5, bootstrap=3)
    return out


def test_a_delayed_speed_loop_is_found_oscillating_and_its_delay_named(delayed):
    d = LC.detect(delayed["delay"])
    assert d["detected"], d
    found = LC.reproduced_by(delayed["delay"], ["sensor_delay", "friction"], d["freq_hz"],
                             d["bin_hz"])
    assert [r["effect"] for r in found] == ["sensor_delay"]
    assert found[0]["params"]["sensor_delay_s"] == pytest.approx(0.004)
    note = LC.note(delayed["delay"], ["sensor_delay"])
    assert note is not None and "sensor_delay_s = 0.004" in note["note"]


def test_the_same_actuator_without_the_delay_shows_none(delayed):
    assert not LC.detect(delayed["nominal"])["detected"]
    assert LC.note(delayed["nominal"], ["sensor_delay"]) is None


def test_the_note_is_printed_under_the_verdict_and_on_the_report(delayed):
    from bench.gap.report import _limit_cycle
    note = LC.note(delayed["delay"], ["sensor_delay"])
    js = {"localisation": {"limit_cycle": note}}
    (para,) = _limit_cycle(js)
    assert para.text.startswith("<b>Limit cycle:</b> the loop oscillates by itself")
    assert _limit_cycle({"localisation": {}}) == []
