"""The ECU and operator side of the EMA ball-screw HUMS bench.

`bench` holds the position/speed controller, the in-process harness, the HUMS monitor,
the sim-to-real gap diagnosis, log tools and the `bench` command. It reaches the live
plant only through the CAN bus (see `bench.bus`); offline studies use the public
model API of `plant_rt`.
"""

__version__ = "0.1.0"


class BenchError(Exception):
    """An error the user can fix: printed as one line ``error: ...`` by the CLI."""


def machine_description() -> str:
    """CPU model, core count and Python version, for benchmark and report headers."""
    import os
    import platform
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    return f"{cpu}, {os.cpu_count()} cores, Python {platform.python_version()}"


def refuse_mf4_import() -> None:
    """python-can imports asammdf (its MF4 log format: asammdf, pandas, sympy) with `import
    can`, 0.6-2 s of CPU at every process's start-up; a process refuses that import (the
    documented `sys.modules[name] = None`), in this process only, until it opens an MF4
    log (`allow_mf4_import`): every `bench` command run as its own process
    (`bench.cli.main`) and the loopback hub (`bench.bus`). `python -m plant_rt` does the
    same for itself (plant_rt does not import bench)."""
    import sys
    if "asammdf" not in sys.modules:
        sys.modules["asammdf"] = None  # type: ignore[assignment]


def allow_mf4_import() -> None:
    """Undo `refuse_mf4_import` before an MF4 log is read or written: asammdf becomes
    importable and python-can's `can.io.mf4` runs again in its own namespace, where the
    MF4 reader and writer classes python-can handed out already (`can.MF4Reader`, the
    table of `can.Logger`) look asammdf up. Nothing to do where it was not refused."""
    import importlib
    import sys
    if "asammdf" in sys.modules and sys.modules["asammdf"] is None:
        del sys.modules["asammdf"]
        import can.io.mf4
        importlib.reload(can.io.mf4)
