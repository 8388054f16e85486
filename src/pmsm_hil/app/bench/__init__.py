"""Benchmarks that measure and print figures (`hil bench ...`)."""
