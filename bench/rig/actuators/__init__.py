"""Actuator descriptions that ship with the bench (`bench.rig.actuator.SHIPPED`) and the
column maps of their rigs' tables (`bench import --map`)."""
