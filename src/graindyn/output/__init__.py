"""What a run writes: run directory, time series, VTK snapshots, checkpoints, progress."""
