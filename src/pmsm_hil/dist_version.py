"""An installed distribution's version without importing `importlib.metadata` (≈ 0.08 CPU-s of a process: email,
zipfile, csv...; a `hil run` and its MCAP logger each asked it once).

`fast_version(name)` gives `importlib.metadata.version(name)`'s answer: the first `.dist-info`/`.egg-info` folder on
`sys.path` whose name normalises as `name`'s (the same search and order), its METADATA (or PKG-INFO) "Version"
header as the email parser reads it. Whatever this reading does not cover (a zip on `sys.path`, another
distribution finder, no such folder, a folded or CR-ended header) is asked of `importlib.metadata` itself."""

from __future__ import annotations

import contextlib
import os
import re
import sys
import types
from collections.abc import Iterator
from importlib.machinery import PathFinder

from pmsm_hil.errors import HilError

_SEPARATORS = re.compile(r"[-_.]+")
#: a line the email parser reads as (part of) a header: `email.feedparser.headerRE`
_HEADER_LINE = re.compile(r"^(From |[\041-\071\073-\176]*:|[\t ])")


def _normalize(name: str) -> str:
    """`importlib.metadata.Prepared.normalize`."""
    return _SEPARATORS.sub("-", name).lower().replace("-", "_")


def _metadata_dirs(name: str) -> Iterator[str] | None:
    """The metadata folders `importlib.metadata` finds for `name`, in its order; None where it searches otherwise."""
    if [f for f in sys.meta_path if hasattr(f, "find_distributions")] != [PathFinder]:
        return None
    roots = list(sys.path)
    if any(not isinstance(root, str) or os.path.isfile(root) for root in roots):
        return None  # a zip's children: importlib.metadata reads them with zipfile
    wanted, legacy = _normalize(name), name.lower().replace("-", "_")

    def found() -> Iterator[str]:
        for root in roots:
            try:
                children = os.listdir(root or ".")
            except OSError:
                continue
            base = os.path.basename(root).lower()
            eggs = []
            for child in children:
                low = child.lower()
                if low.endswith((".dist-info", ".egg-info")):
                    if _normalize(low.rpartition(".")[0].partition("-")[0]) == wanted:
                        yield os.path.join(root, child)
                elif (base.endswith(".egg") and low == "egg-info"
                      and base.rpartition(".")[0].partition("-")[0].replace("-", "_") == legacy):
                    eggs.append(os.path.join(root, child))
            yield from eggs

    return found()


def _read(folder: str, file: str) -> str | None:
    """The file's text; None where importlib.metadata's `read_text` gives None (other errors are raised)."""
    with contextlib.suppress(FileNotFoundError, IsADirectoryError, NotADirectoryError, PermissionError), \
            open(os.path.join(folder, file), encoding="utf-8") as f:
        return f.read()
    return None


def _header_version(text: str) -> str | None:
    """The "Version" header's value as `email.message_from_string(text)["Version"]` gives it; None where its
    parser would read something this does not (CR line ends, a folded header, no such header)."""
    if "\r" in text:
        return None
    lines = text.split("\n")
    for i, line in enumerate(lines):
        if not _HEADER_LINE.match(line):
            return None  # the headers' end (a blank line, or the body begun without one)
        key, colon, value = line.partition(":")
        if colon and key.lower() == "version":
            following = lines[i + 1] if i + 1 < len(lines) else ""
            return None if following[:1] in (" ", "\t") else value.lstrip(" \t")
    return None


def fast_version(name: str) -> str | None:
    """`name`'s version read without `importlib.metadata`; None where that has to answer."""
    dirs = _metadata_dirs(name)
    folder = next(dirs, None) if dirs is not None else None
    if folder is None:
        return None
    try:
        text = _read(folder, "METADATA") or _read(folder, "PKG-INFO")
    except (OSError, UnicodeDecodeError):
        return None
    return _header_version(text) if text else None


def installed_version(name: str, missing: str) -> str:
    """`importlib.metadata.version(name)` (without its import where `fast_version` answers), `missing` where it
    raises `PackageNotFoundError`."""
    found = fast_version(name)
    if found is not None:
        return found
    from importlib import metadata

    try:
        return metadata.version(name)
    except metadata.PackageNotFoundError:
        return missing


class _PackageNotFoundError(HilError, ModuleNotFoundError):
    """`importlib.metadata.PackageNotFoundError` as `light_metadata`'s stand-in raises it."""


@contextlib.contextmanager
def light_metadata() -> Iterator[None]:
    """While a third-party module is imported that only asks `importlib.metadata` for a version at its import (mcap's
    writer: its default library name): `importlib.metadata` answers with `fast_version` (the real one where that
    cannot), and is the real one again afterwards. Nothing changes where the real one is already loaded."""
    if "importlib.metadata" in sys.modules:
        yield
        return

    def shim_version(name: str) -> str:
        found = fast_version(name)
        if found is not None:
            return found
        sys.modules.pop("importlib.metadata", None)
        from importlib import metadata  # the real one, loaded from now on

        try:
            return metadata.version(name)
        except metadata.PackageNotFoundError:
            raise _PackageNotFoundError(name) from None

    shim = types.ModuleType("importlib.metadata", "`light_metadata`'s stand-in: `version` only")
    shim.version = shim_version  # type: ignore[attr-defined]
    shim.PackageNotFoundError = _PackageNotFoundError  # type: ignore[attr-defined]
    sys.modules["importlib.metadata"] = shim
    try:
        yield
    finally:
        if sys.modules.get("importlib.metadata") is shim:
            del sys.modules["importlib.metadata"]
