"""Closed-loop runner: scenarios, host side of the protocol, lockstep and real-time loops."""
