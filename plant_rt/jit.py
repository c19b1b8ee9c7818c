"""Where numba keeps its compiled code: a cache directory keyed by the source of every
compiled module, so a changed kernel can never run from a stale cache.

numba's own cache (``cache=True``) checks only the file that holds the function it
caches. A compiled loop in `bench.sim.loop` inlines `plant_rt.kernel.advance`; after the
kernel changes (an upgrade, a checkout, a merge) numba still loads the old loop from
``__pycache__`` and the plant runs old physics with no warning (seen on this
repository: the Archard wear state stayed 0.0 until the cache files were deleted). Here
the cache directory is named after a hash of every module of `plant_rt` and `bench` that
compiles code, so any change there starts a fresh cache. Every module that compiles
takes `njit` from here (``from plant_rt.jit import njit``), which configures the cache
before numba is imported (tests/unit/test_layout.py checks that no other module imports
numba's `njit`). ``$NUMBA_CACHE_DIR`` set by the user wins.
"""

from __future__ import annotations

import hashlib
import os
import sys
import tempfile
from pathlib import Path

_ROOTS = ("plant_rt", "bench")
_configured: str | None = None


def compiled_sources(root: Path | None = None) -> list[Path]:
    """The .py files of `plant_rt` and `bench` that hold compiled (njit) code."""
    base = root if root is not None else Path(__file__).resolve().parent.parent
    out = []
    for pkg in _ROOTS:
        for path in sorted((base / pkg).rglob("*.py")):
            try:
                if "njit" in path.read_text(encoding="utf-8"):
                    out.append(path)
            except OSError:
                continue
    return out


def cache_key(files: list[Path]) -> str:
    """A short hash of the files' names and bytes, and of the Python version."""
    h = hashlib.sha256(sys.version.encode())
    for path in files:
        h.update(path.name.encode())
        h.update(path.read_bytes())
    return h.hexdigest()[:16]


def _base_dir() -> Path:
    home = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache"))
    base = home / "ema-hums-bench" / "numba"
    try:
        base.mkdir(parents=True, exist_ok=True)
        if os.access(base, os.W_OK):
            return base
    except OSError:
        pass
    return Path(tempfile.gettempdir()) / "ema-hums-bench-numba"


def configure() -> str:
    """Point numba's cache at the directory of the current sources (once per process);
    returns that directory."""
    global _configured
    if _configured is not None:
        return _configured
    path = os.environ.get("NUMBA_CACHE_DIR") or ""
    if not path:
        path = str(_base_dir() / cache_key(compiled_sources()))
        os.environ["NUMBA_CACHE_DIR"] = path
    numba = sys.modules.get("numba")
    if numba is not None:   # numba read its configuration already: tell it too
        numba.config.CACHE_DIR = path
    _configured = path
    return path


configure()

from numba import njit  # noqa: E402 - after configure(): numba reads its cache dir now

__all__ = ["njit", "configure", "cache_key", "compiled_sources"]
