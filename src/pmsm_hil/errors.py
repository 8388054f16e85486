"""The one exception root of the package: every error class of `pmsm_hil` derives from `HilError`.

Subclasses keep the built-in base that says what went wrong (`ValueError` for a bad value, `RuntimeError` for a
failed step, `AssertionError` for a signal check), so `except ValueError` still catches them; `hil` reports any
`HilError` in one line naming the field (docs/architecture.md, "Exceptions"). Imports nothing: every layer may
use it.
"""

from __future__ import annotations


class HilError(Exception):
    """Base of every error raised by `pmsm_hil` for bad input or a failed run; the message names the field."""


__all__ = ["HilError"]
