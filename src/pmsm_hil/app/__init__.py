"""The application layer: the `hil` command line, paper comparisons, sweeps and benchmarks (`pmsm_hil.app`)."""
