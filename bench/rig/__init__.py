"""Real rigs without a physics model that fits them: a baseline built from
several healthy runs, aligned by set-point phase (`baseline`), position-locked and
direction-split features against it (`features`), thresholds from held-out healthy runs
and detection / false-alarm rates per condition (`population`), the study of a rig's
development set (`study`), its figures and report (`report`). See docs/real-data.md.

The tables are read by `cycles`: one motion cycle per row group (e.g. the Cranfield
rig's `group` column), at the rig's own sample instants (nothing is resampled)."""
