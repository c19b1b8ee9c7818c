"""The compute runtime: the Dask engine (workers, cluster, its worker plugin) and Ctrl-C handling."""
