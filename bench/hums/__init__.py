"""Health and usage monitoring (thesis chapter 6), and past it.

- `bench.hums.monitor`: the monitoring model of eq. 6.1-6.2 (the nominal actuator the HUMS
  trusts), compiled, driven by the same set-points with the bus timing, and the
  Nelder-Mead fit of its position gain (row H1).
- `bench.hums.indexes`: the public face of the indexes, whole-trace and per command
  period (online), from `formulas` (mean position error 6.4, fidelity coefficients Cp and
  Ci 6.5-6.6 in the ratio-of-integrals reading, peak-current ratio 6.7, lost-motion and
  dead-time readings), `spectra` (the calibrated current spectrum 6.3 with harmonic
  features), `motion` (the streaming signals behind lost motion and reversal dead time),
  `comparison` (`Indexes` of one window), `gaps` (lost samples) and `periods` (per
  command period, `OnlineHums`).
- `bench.hums.sweep`: the 11-point degradation sweep (rows H2-H6) with figures.
- `bench.hums.rul`: the thesis' RUL algorithm (section 6.5): Ci levels, the cubic trend
  fit extrapolated to failure with a bootstrap band, and the `Prediction` every predictor
  returns.
- `bench.hums.records`: a run's per-period indexes with truth (the degradation-schedule
  run) and its true failure time.
- `bench.hums.fusion`: the fused backlash estimate and its predictor (beyond the thesis);
  `bench.hums.calibration` builds its calibration from runs.
- `bench.hums.metrics`: prognostic metrics with progpy.
- `bench.hums.rul_run`: rows R1-R2 (the 120 s run), figures and text;
  `bench.hums.campaign`: the run-to-failure campaign, its table, JSON and figure.
- `bench.hums.report`: self-contained HTML report of one or more logs.

Every computation reads a `bench.signals.trace.Trace` (in-process run, live bus run, decoded
candump log or imported table) and only its measured columns; simulation truth columns
are used for ground truth in studies, never by the monitor.
"""
