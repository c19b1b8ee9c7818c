"""`python -m plant_rt`: the plant as a CANopen node (see `plant_rt.cli`)."""

import sys

# python-can imports asammdf (its MF4 log format) with `import can`, ~0.7 s of every node's
# start-up; the node reads and writes no log file, so that import is refused here (the
# documented `sys.modules[name] = None`), in this process only.
if "asammdf" not in sys.modules:
    sys.modules["asammdf"] = None  # type: ignore[assignment]

from plant_rt.cli import main  # noqa: E402

raise SystemExit(main())
