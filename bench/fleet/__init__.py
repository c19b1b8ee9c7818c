"""The fleet layer (`bench fleet`): many actuators, many logs, one DuckDB store of their
health and usage. One module per job: `schema` (tables and migrations), `store`
(batched writes, reads, Parquet export), `ingest` (logs in, idempotent and resumable),
`status` (one line per actuator), `report` (HTML with figures), `synth` (a synthetic
fleet of ground-test logs). docs/fleet.md is the user's guide."""
