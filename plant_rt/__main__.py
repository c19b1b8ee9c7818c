"""`python -m plant_rt`: the plant as a CANopen node (see `plant_rt.cli`)."""

from plant_rt.cli import main

raise SystemExit(main())
