"""A drive bench as a labgrid place (docs/bench_setup.md "Benches shared through labgrid"): the labgrid resources,
drivers and strategy of a bench (`pmsm_hil.bench.labgrid_parts`, needs the `bench` extra), the place's lease through
labgrid's coordinator (`pmsm_hil.bench.place`), the simulated board (`pmsm_hil.bench.sim_board`) and the wait for a
target's heartbeat (`pmsm_hil.bench.heartbeat`). Importing this package imports no labgrid."""
