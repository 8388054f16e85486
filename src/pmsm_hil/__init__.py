"""pmsm-hil: hardware-in-the-loop PMSM drive tester.

Import root for the repository folders hil/, protocol/, sim_target/ and dashboards/
(mapped in pyproject.toml so no bare top-level `protocol` module is installed)."""
