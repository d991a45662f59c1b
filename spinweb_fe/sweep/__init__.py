"""Parameter sweeps on Dask: the runs and their summary."""
