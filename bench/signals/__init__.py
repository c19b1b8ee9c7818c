"""Signals: the trace (one row per SYNC period), the one table reader, the units of a rig's quantities, and the estimators of a signal."""
