"""cffi declarations taken from the C headers themselves, so the build scripts never restate a struct or a
prototype (hil/native/_build_plant.py, _build_loop.py, and `kernel_build` for a kind's kernel).

`declarations(header, names)` returns the named typedefs and prototypes of a header, in the order of `names`, with
comments, preprocessor lines and `NL_PACKED` removed and integer macros in array sizes replaced by their values;
`constants(header)` the header's integer `#define`s as cffi `#define NAME ...` lines. Pure text: importable by path
from a build script (no package import).
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from pathlib import Path

_COMMENT = re.compile(r"/\*.*?\*/|//[^\n]*", re.S)
_DEFINE = re.compile(r"^\s*#\s*define\s+([A-Z_][A-Z0-9_]*)\s+\(?\s*(-?(?:0x[0-9a-fA-F]+|\d+))[uU]?\s*\)?\s*$", re.M)
_FUNCTION_NAME = re.compile(r"([A-Za-z_]\w*)\s*\(")
_TRAILING_NAME = re.compile(r"([A-Za-z_]\w*)\s*$")


def _clean(text: str) -> str:
    text = _COMMENT.sub(" ", text)
    text = re.sub(r"\\\n", " ", text)  # continued macro lines
    return "\n".join(line for line in text.splitlines() if not line.lstrip().startswith("#"))


def constants(header: Path) -> dict[str, int]:
    """The header's integer `#define NAME value` macros."""
    text = _COMMENT.sub(" ", header.read_text(encoding="utf-8"))
    return {m.group(1): int(m.group(2), 0) for m in _DEFINE.finditer(text)}


def cffi_constants(header: Path, prefix: str = "") -> str:
    """`#define NAME ...` for each integer macro of the header whose name starts with `prefix`."""
    return "".join(f"#define {name} ...\n" for name in constants(header) if name.startswith(prefix))


def _split(text: str) -> list[str]:
    """Top-level declarations (up to each `;` at brace and parenthesis depth 0)."""
    out, depth, start = [], 0, 0
    for i, ch in enumerate(text):
        if ch in "{(":
            depth += 1
        elif ch in "})":
            depth -= 1
        elif ch == ";" and depth == 0:
            out.append(text[start:i + 1].strip())
            start = i + 1
    return [d for d in out if d]


def _name(decl: str) -> str | None:
    """The name a declaration declares: a typedef's last identifier, a function's name, a struct's tag."""
    body = decl.rstrip(";").strip()
    if body.startswith("typedef"):
        if body.endswith(")"):  # a function pointer typedef: typedef int (*name)(...)
            m = re.search(r"\(\s*\*\s*([A-Za-z_]\w*)\s*\)", body)
            return m.group(1) if m else None
        m = _TRAILING_NAME.search(body)
        return m.group(1) if m else None
    if "(" in body and "{" not in body:
        m = _FUNCTION_NAME.search(body)
        return m.group(1) if m else None
    return None


def declarations(header: Path, names: Iterable[str], macros: dict[str, int] | None = None) -> str:
    """The named declarations of `header` as cffi cdef text; KeyError naming any name the header lacks.
    `macros`: integer macros for array sizes (default: the header's own)."""
    wanted = list(names)
    values = constants(header) if macros is None else macros
    found: dict[str, str] = {}
    for decl in _split(_clean(header.read_text(encoding="utf-8"))):
        name = _name(decl)
        if name in wanted:
            text = decl.replace("NL_PACKED", "")
            text = re.sub(r"\[\s*([A-Z_][A-Z0-9_]*)\s*\]", lambda m: f"[{values[m.group(1)]}]", text)
            found[name] = text
    missing = [n for n in wanted if n not in found]
    if missing:
        raise KeyError(f"{header.name}: no declaration of {', '.join(missing)}")
    return "\n".join(found[n] for n in sorted(found, key=wanted.index)) + "\n"


__all__ = ["cffi_constants", "constants", "declarations"]
