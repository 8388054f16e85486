"""The test suite's reference (oracle) Python period loop."""
