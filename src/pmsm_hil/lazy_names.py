"""Package names loaded on first use (PEP 562): a package's `__init__` maps each public name to the module that
defines it, so importing the package imports none of those modules (a process pays only for what it uses)."""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from typing import Any


def lazy_getattr(package: str, names: Mapping[str, str], namespace: dict[str, Any]) -> Callable[[str], Any]:
    """The module `__getattr__` of `package`: `names` maps a public name to the module defining it; the name is
    imported on its first use and kept in `namespace` (the package's `globals()`), so later uses are plain lookups."""

    def load(name: str) -> Any:
        module = names.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(module), name)
        namespace[name] = value
        return value

    return load
