"""What a decoded log lost, repeated or had out of order: `bench.signals.integrity` (kept
there, beside the trace whose ``meta`` it reads, so that a reader of a trace need not
import the bus and python-can)."""

from bench.signals.integrity import integrity

__all__ = ["integrity"]
