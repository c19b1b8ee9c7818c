"""numba's cache is keyed by every compiled module's source (plant_rt/jit.py): a
compiled loop that inlines a changed kernel must never load from a stale cache (it did:
the Archard wear state read 0.0 after a merge until the cache files were deleted)."""

from __future__ import annotations

import os
import re
from pathlib import Path

import numba

from plant_rt import jit

ROOT = Path(__file__).resolve().parents[2]


def test_the_cache_directory_is_named_after_the_compiled_sources():
    import plant_rt.kernel  # noqa: F401 - compiles through plant_rt.jit
    path = jit.configure()
    assert numba.config.CACHE_DIR == path
    if not os.environ.get("EMA_TEST_USER_NUMBA_CACHE_DIR"):
        assert path.endswith(jit.cache_key(jit.compiled_sources()))


def test_the_key_changes_when_any_compiled_module_changes(tmp_path):
    for pkg in ("plant_rt", "bench"):
        (tmp_path / pkg).mkdir()
    kernel = tmp_path / "plant_rt" / "kernel.py"
    loop = tmp_path / "bench" / "loop.py"
    plain = tmp_path / "bench" / "report.py"
    kernel.write_text("@njit\ndef advance(): return 1\n")
    loop.write_text("@njit\ndef run(): return advance()\n")
    plain.write_text("def report(): return 1\n")
    files = jit.compiled_sources(tmp_path)
    assert files == [kernel, loop]
    key = jit.cache_key(files)
    plain.write_text("def report(): return 2\n")           # no compiled code: same cache
    assert jit.cache_key(jit.compiled_sources(tmp_path)) == key
    kernel.write_text("@njit\ndef advance(): return 2\n")  # the inlined kernel changed
    assert jit.cache_key(jit.compiled_sources(tmp_path)) != key


def test_no_module_takes_njit_from_numba_directly():
    offenders = []
    for pkg in ("plant_rt", "bench"):
        for path in (ROOT / pkg).rglob("*.py"):
            if path.name == "jit.py" and path.parent.name == "plant_rt":
                continue
            text = path.read_text(encoding="utf-8")
            if re.search(r"^\s*(from numba import .*\bnjit\b|import numba\b)", text, re.M):
                offenders.append(str(path.relative_to(ROOT)))
    assert offenders == [], f"import njit from plant_rt.jit: {offenders}"
