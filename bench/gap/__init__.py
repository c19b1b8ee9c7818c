"""Sim-to-real gap diagnosis (docs/gap.md).

Where the gap between a log and the nominal model lies (signal, path, regime, frequency
band), which unmodelled effect causes it (a library of bounded, physically parameterised
candidate effects fitted by least squares, ranked by BIC, pairs by forward selection) and
how far it shrinks on held-out data. See docs/gap.md.

    from bench.gap.diagnose import Options, diagnose
    result = diagnose(trace)            # bench.signals.trace.Trace of a logged run
    result.json()                       # {"localisation", "ranking", "verdict"}

Modules: `resim` (re-simulation of a logged run and of single paths), `problem` (floors,
residuals), `localise`, `effects` (registry) and `library` (built-in effects), `fit`,
`diagnose`, `calibrate`, `importer`, `blind` (the blind benchmark), `report`, `models`.
"""

