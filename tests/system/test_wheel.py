"""The built wheel works on its own: `pip wheel` of the checkout, installed with --no-deps
into a clean virtual environment (its dependencies from the running interpreter's
site-packages, so nothing is downloaded but pip's own build requirements from its
configured indexes), then `bench demo --in-process` run from it with the working
directory outside the checkout and no PYTHONPATH, so the checkout's files (the DBC, the
EDS) cannot be found by accident. The bus description's source is the checkout's
top-level dbc/; the wheel carries it as ema_contract/dbc/ (setup.py's build step).

The suite may itself run inside a virtual environment (the README's way on a PEP 668
system): `python -m venv --system-site-packages` then links the new environment to the
base interpreter's site-packages, where the dependencies are not, so `import can` failed.
The dependencies are where the running interpreter finds them: its own site-packages
are listed in a ``.pth`` file of the new environment (directories only, so their ``.pth``
files, an editable install of the checkout among them, are not run)."""

from __future__ import annotations

import os
import re
import shutil
import site
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def _run(cmd: list[str], cwd: Path, env: dict[str, str], timeout: float
         ) -> subprocess.CompletedProcess:
    r = subprocess.run(cmd, cwd=str(cwd), env=env, capture_output=True, text=True,
                       timeout=timeout)
    assert r.returncode == 0, f"{cmd}\n{r.stdout[-3000:]}\n{r.stderr[-3000:]}"
    return r


def running_site_packages() -> list[str]:
    """The site-packages of the running interpreter when it is a virtual environment's
    (where its dependencies are), else none (`--system-site-packages` has them)."""
    if sys.prefix == sys.base_prefix:
        return []
    return [p for p in site.getsitepackages() if Path(p).is_dir()]


def _see_running_site_packages(py: Path, cwd: Path, env: dict[str, str]) -> None:
    """A ``.pth`` in the new environment `py` listing `running_site_packages`."""
    dirs = running_site_packages()
    if not dirs:
        return
    purelib = _run([str(py), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                   cwd, env, 120).stdout.strip()
    (Path(purelib) / "_running_site_packages.pth").write_text("\n".join(dirs) + "\n")


@pytest.fixture(scope="module")
def venv(tmp_path_factory) -> tuple[Path, dict[str, str], Path]:
    """A virtual environment with the wheel built from this checkout installed."""
    tmp = tmp_path_factory.mktemp("wheel")
    env = {k: v for k, v in os.environ.items()
           if k not in ("PYTHONPATH", "PYTHONHOME", "EMA_BENCH_DBC_DIR")}
    env["BENCH_STATE_DIR"] = str(tmp / "state")
    # build from a copy: setuptools leaves build/ and *.egg-info next to the sources, and
    # a stale build/lib would put files deleted since into the wheel
    src = tmp / "src"
    shutil.copytree(ROOT, src, ignore=shutil.ignore_patterns(
        ".git", "build", "dist", "*.egg-info", "out", ".bench", "__pycache__", ".*_cache",
        ".hypothesis"))
    dist = tmp / "dist"
    _run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--quiet", "-w", str(dist),
          str(src)], tmp, env, 600)
    wheels = list(dist.glob("ema_hums_bench-*.whl"))
    assert len(wheels) == 1, wheels
    subprocess.run([sys.executable, "-m", "venv", "--system-site-packages", str(tmp / "venv")],
                   check=True, timeout=120)
    py = tmp / "venv" / "bin" / "python"
    _see_running_site_packages(py, tmp, env)
    # --ignore-installed: the system site-packages may hold an editable install of the
    # checkout; the venv's own copy shadows it
    _run([str(py), "-m", "pip", "install", "--no-deps", "--ignore-installed", "--quiet",
          str(wheels[0])], tmp, env, 300)
    return tmp / "venv", env, wheels[0]


def test_wheel_holds_the_four_packages_and_the_bus_description(venv):
    root, env, wheel = venv
    names = zipfile.ZipFile(wheel).namelist()
    top = {n.split("/")[0] for n in names if not n.split("/")[0].endswith(".dist-info")}
    assert top == {"bench", "plant_rt", "ema_contract", "indie_plant"}, top
    assert {"ema_contract/dbc/ema.dbc", "ema_contract/dbc/ema.eds"} <= set(names)
    assert {"bench/reports/style.css", "bench/reports/templates/base.html.j2",
            "bench/reports/templates/hums_report.html.j2",
            "bench/reports/templates/document.html.j2"} <= set(names)      # report pages
    code = ("import bench, ema_contract; "
            "from ema_contract.frames import dbc_path, eds_path, load_od, Frames; "
            "print(bench.__file__); print(ema_contract.__file__); print(dbc_path()); "
            "print(eds_path()); Frames(); load_od()")
    out = _run([str(root / "bin" / "python"), "-c", code], root.parent, env,
               120).stdout.split()
    assert len(out) == 4, out
    for path in out:
        assert Path(path).resolve().is_relative_to(root.resolve()), out
    assert Path(out[2]).parts[-3:] == ("ema_contract", "dbc", "ema.dbc"), out
    with zipfile.ZipFile(wheel) as zf:                 # the checkout's files, unchanged
        for name in ("ema.dbc", "ema.eds"):
            assert zf.read(f"ema_contract/dbc/{name}") == (ROOT / "dbc" / name).read_bytes()
    dump = _run([str(root / "bin" / "python"), "-m", "cantools", "dump", out[2]],
                root.parent, env, 120).stdout
    assert "EMA_TPDO1" in dump and "MotorCurrent" in dump, dump[-2000:]


def test_cantools_dumps_the_checkouts_dbc():
    """`cantools dump dbc/ema.dbc` from the checkout: the source file, as a user reads it."""
    env = {k: v for k, v in os.environ.items() if k != "EMA_BENCH_DBC_DIR"}
    dump = _run([sys.executable, "-m", "cantools", "dump", "dbc/ema.dbc"], ROOT, env,
                120).stdout
    for message in ("EMA_TPDO1", "EMA_RPDO1", "ECU_Setpoint"):
        assert re.search(rf"Name: +{message}\n", dump), dump[-2000:]


def test_bench_demo_runs_from_the_wheel(venv):
    root, env, _ = venv
    out = root.parent / "demo"
    r = _run([str(root / "bin" / "bench"), "demo", "--in-process", "--cycles", "1",
              "--no-gap", "--out", str(out)], root.parent, env, 900)
    assert "verdict" in r.stdout and "lost motion um" in r.stdout, r.stdout
    rows = [line.split() for line in r.stdout.splitlines()
            if line.strip().startswith(("healthy", "worn", "end-of-life"))
            and ".npz " in line]
    assert [row[0] for row in rows] == ["healthy.npz", "worn.npz", "end-of-life.npz"], r.stdout
    assert rows[0][1] == "HEALTHY"
    assert (out / "hums" / "report.html").is_file() and (out / "summary.json").is_file()
    assert "<nav>" in (out / "hums" / "report.html").read_text()     # the templates' page
