"""`bench reproduce` and the gap report draw with matplotlib's Figure API: no pyplot, no
backend switch inside library code."""

from __future__ import annotations

import subprocess
import sys

CODE = """
import sys
import numpy as np
from bench.sim.freqresp import FreqResponse
from bench.studies.reproduce import Result, figures
f = np.geomspace(1, 100, 20)
res = Result(responses={"x": FreqResponse("x", f, 1 / (1 + 1j * f / 10))})
names = [p.name for p in figures(res, sys.argv[1])]
import bench.gap.report
print(names)
print('matplotlib.pyplot' in sys.modules)
"""


def test_reproduce_figures_without_pyplot(tmp_path):
    r = subprocess.run([sys.executable, "-c", CODE, str(tmp_path)], capture_output=True,
                       text=True, timeout=300, check=True)
    names, pyplot = r.stdout.strip().splitlines()
    assert names == "['p5_p7_bode.png']"
    assert (tmp_path / "p5_p7_bode.png").stat().st_size > 1000
    assert pyplot == "False"
