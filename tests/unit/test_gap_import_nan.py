"""`bench import` of a table with a NaN block: the block is reported (rows,
time span) and its SYNC-grid samples are left empty, as lost samples of a decoded log,
for the HUMS and the gap diagnosis to bridge or refuse; a channel logged at a lower rate
is not a block."""

from __future__ import annotations

import json

import numpy as np
import pytest

from bench.gap.importer import import_table, read_map
from bench.hums import report as HR

MAP = {"t_s": {"column": "t", "unit": "s"},
       "position_m": {"column": "x", "unit": "mm"},
       "current_a": {"column": "i", "unit": "A"},
       "setpoint_position_m": {"column": "sp", "unit": "mm"},
       "setpoint_speed_rad_s": {"column": "w", "unit": "rad/s"},
       "mode": {"column": "mode", "unit": "-"}}


def _table(tmp_path, blank: slice | None, slow: bool = False):
    tt = np.arange(3000) * 1e-3
    t = tt.tolist()
    x = (0.5 * np.sin(2 * np.pi * 2 * tt)).tolist()
    cur = (0.8 * np.cos(2 * np.pi * 2 * tt)).tolist()
    rows = ["t,x,i,sp,w,mode"]
    for k in range(len(t)):
        missing = (blank is not None and blank.start <= k < blank.stop) or (slow and k % 7 == 3)
        rows.append(f"{t[k]!r},{x[k]!r},{'' if missing else repr(cur[k])},{x[k]!r},0,1")
    (tmp_path / "rig.csv").write_text("\n".join(rows) + "\n")
    (tmp_path / "map.json").write_text(json.dumps(MAP))
    return import_table(tmp_path / "rig.csv", read_map(tmp_path / "map.json"), 1e-3)


def test_a_nan_block_is_reported_and_left_empty(tmp_path):
    tr = _table(tmp_path, slice(1000, 1100))
    assert tr.meta["nan_blocks"] == [{
        "signal": "current_a", "column": "i", "first_row": 1001, "last_row": 1100,
        "rows": 100, "t0_s": pytest.approx(0.999), "t1_s": pytest.approx(1.100),
        "samples": 100}]
    cur = tr["current_a"]
    assert np.isnan(cur[1000:1100]).all()
    assert np.isfinite(cur[:1000]).all() and np.isfinite(cur[1100:]).all()
    assert np.isfinite(tr["position_m"]).all()
    from bench.signals.integrity import integrity
    assert integrity(tr.meta) == ["NaN block in i (current_a): table rows 1001-1100, "
                                  "t = 0.999-1.100 s, 100 SYNC samples left empty"]


def test_a_slower_channel_is_not_a_block(tmp_path):
    tr = _table(tmp_path, None, slow=True)
    assert tr.meta["nan_blocks"] == []
    assert np.isfinite(tr["current_a"]).all()


def test_the_hums_treats_a_block_as_lost_samples(tmp_path):
    long = HR.analyse(_table(tmp_path, slice(1000, 1100)), "long", rul=False)
    assert long.indexes.unavailable["ci"].startswith(
        "not available: 100 samples missing in current_a")
    short = HR.analyse(_table(tmp_path, slice(1000, 1003)), "short", rul=False)
    assert short.bridged == {"current_a": 3} and "ci" not in short.indexes.unavailable
