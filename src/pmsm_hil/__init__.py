"""pmsm-hil: hardware-in-the-loop PMSM drive tester.

Import root: every folder below src/pmsm_hil/ is its import path (src/pmsm_hil/hil/runner is pmsm_hil.hil.runner);
no bare top-level `protocol` or `hil` module is installed."""
