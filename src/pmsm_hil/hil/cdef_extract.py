"""cffi declarations taken from the C headers themselves, so the build scripts never restate a struct, a prototype or
a constant (src/pmsm_hil/hil/kernels/_build_plant.py, src/pmsm_hil/hil/runner/c/_build_loop.py,
src/pmsm_hil/sim_target/_build_firmware.py, and `kernel_build` for a kind's kernel).

`declarations(header, names)` returns the named typedefs and prototypes of a header (or of a kind's one C file,
tests/runner/rl_kind), in the order of `names`, with comments, preprocessor lines, `static` / `inline` and
`NL_PACKED` removed and integer macros in array sizes replaced by their values. It cuts a struct down to the fields
cffi needs (`partial`: the kept fields and `...;`, cffi then checks their offsets and the struct's size against the
real header when it compiles), declares a tagged struct opaque (`opaque`: `typedef struct tag name;`), declares a
function the cffi module defines in Python (`extern_python`), and takes a function's prototype from its definition
(a glue header's `static` functions). `constants(*headers)` gives the integer `#define`s of headers (literals and
integer expressions of other macros of the same headers, or of `known`), `cffi_constants(header, prefix)` the
header's own as cffi `#define NAME ...` lines, and `declared_names(text)` what a piece of C declares (the test that
no build script restates a header uses it). Pure text: importable by path from a build script (no package import).
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping
from pathlib import Path

_COMMENT = re.compile(r"/\*.*?\*/|//[^\n]*", re.S)
_OBJECT_MACRO = re.compile(r"^[ \t]*#[ \t]*define[ \t]+([A-Za-z_]\w*)[ \t]+([^\n]+?)[ \t]*$", re.M)
_TOKEN = re.compile(r"\s*(?:(0[xX][0-9a-fA-F]+|\d+)[uUlL]*|([A-Za-z_]\w*)|(<<|>>|[-+*/%()|&^~]))")
_FUNCTION_NAME = re.compile(r"([A-Za-z_]\w*)\s*\(")
_TRAILING_NAME = re.compile(r"([A-Za-z_]\w*)\s*$")
_POINTER_NAME = re.compile(r"\(\s*\*\s*([A-Za-z_]\w*)\s*\)")
_DECLARATOR = re.compile(r"^(.*?)\s*((?:\*\s*)*[A-Za-z_]\w*\s*(?:\[[^\]]*\]\s*)*)$", re.S)
_ARRAY_SIZE = re.compile(r"\[([^\]]*)\]")
_STORAGE = re.compile(r"^(?:(?:static|inline|__inline__)\s+)+")


def _clean(text: str) -> str:
    """Declarations only: no comments, preprocessor lines, or C++-only lines (`#ifdef __cplusplus`: `extern "C" {`)."""
    text = _COMMENT.sub(" ", text)
    text = re.sub(r"\\\n", " ", text)  # continued macro lines
    lines, cplusplus = [], 0
    for line in text.splitlines():
        directive = re.match(r"\s*#\s*(\w+)\s*(\w*)", line)
        if directive is None:
            if not cplusplus:
                lines.append(line)
        elif directive.group(1) in ("if", "ifdef", "ifndef") and (cplusplus or directive.group(2) == "__cplusplus"):
            cplusplus += 1
        elif directive.group(1) == "endif" and cplusplus:
            cplusplus -= 1
    return "\n".join(lines)


class _Expr:
    """A C integer constant expression of literals and known macros: + - * / % << >> & | ^ ~ and parentheses, C's
    precedence and division truncating toward zero; `value` is None for anything else (a cast, an unknown name)."""

    def __init__(self, text: str, known: Mapping[str, int]) -> None:
        self.tokens: list[tuple[str, str]] = []
        pos, text = 0, text.strip()
        while pos < len(text):
            m = _TOKEN.match(text, pos)
            if m is None:
                raise ValueError(text)
            pos = m.end()
            kind = "num" if m.group(1) else "name" if m.group(2) else "op"
            self.tokens.append((kind, m.group(m.lastindex or 0)))
        self.known, self.at = known, 0

    def value(self) -> int:
        v = self._binary(0)
        if self.at != len(self.tokens):
            raise ValueError("trailing tokens")
        return v

    _LEVELS = (("|",), ("^",), ("&",), ("<<", ">>"), ("+", "-"), ("*", "/", "%"))

    def _peek(self) -> str | None:
        return self.tokens[self.at][1] if self.at < len(self.tokens) else None

    def _binary(self, level: int) -> int:
        if level == len(self._LEVELS):
            return self._unary()
        v = self._binary(level + 1)
        while self._peek() in self._LEVELS[level]:
            op = self.tokens[self.at][1]
            self.at += 1
            w = self._binary(level + 1)
            if op in "/%" and w == 0:
                raise ValueError("division by zero")
            q = abs(v) // abs(w) * (1 if (v < 0) == (w < 0) else -1) if op in "/%" else 0
            v = {"|": v | w, "^": v ^ w, "&": v & w, "<<": v << w, ">>": v >> w, "+": v + w, "-": v - w,
                 "*": v * w, "/": q, "%": v - q * w}[op]
        return v

    def _unary(self) -> int:
        if self.at >= len(self.tokens):
            raise ValueError("missing operand")
        kind, tok = self.tokens[self.at]
        self.at += 1
        if tok in ("-", "+", "~"):
            v = self._unary()
            return -v if tok == "-" else ~v if tok == "~" else v
        if tok == "(":
            v = self._binary(0)
            if self._peek() != ")":
                raise ValueError("unbalanced")
            self.at += 1
            return v
        if kind == "num":
            return int(tok, 0) if not re.fullmatch(r"0\d+", tok) else int(tok, 8)
        if kind == "name" and tok in self.known:
            return self.known[tok]
        raise ValueError(tok)


def evaluate(text: str, known: Mapping[str, int]) -> int | None:
    """The value of the integer constant expression `text` over the macros `known`, or None."""
    try:
        return _Expr(text, known).value()
    except ValueError:
        return None


def _macros(header: Path) -> list[tuple[str, str]]:
    text = re.sub(r"\\\n", " ", _COMMENT.sub(" ", header.read_text(encoding="utf-8")))
    return [(m.group(1), m.group(2)) for m in _OBJECT_MACRO.finditer(text)]


def constants(*headers: Path, known: Mapping[str, int] | None = None) -> dict[str, int]:
    """The integer object-like `#define NAME value` macros of the headers, in the order they are defined: a literal,
    or an integer expression of other macros of these headers or of `known` (an array size in one header given by a
    macro of another: pass both). ValueError naming a macro two of them define with different values."""
    defined = [(name, body) for header in headers for name, body in _macros(header)]
    values: dict[str, int] = dict(known or {})
    resolved: dict[str, int] = {}
    progress = True
    while progress:  # a macro may use one defined further down (C expands at the use)
        progress = False
        for name, body in defined:
            v = evaluate(body, values)
            if v is None:
                continue
            if name in resolved and resolved[name] != v:
                raise ValueError(f"{name} is defined as both {resolved[name]} and {v}")
            if name not in resolved:
                resolved[name] = values[name] = v
                progress = True
    order = {name: i for i, (name, _) in reversed(list(enumerate(defined)))}
    return dict(sorted(resolved.items(), key=lambda item: order[item[0]]))


def cffi_constants(header: Path, prefix: str = "", names: Iterable[str] | None = None,
                   macros: Mapping[str, int] | None = None) -> str:
    """`#define NAME ...` for each integer macro of the header whose name starts with `prefix`, or for the macros
    `names` (KeyError naming one the header lacks); `macros`: those of other headers its own may use."""
    own = list(constants(header, known=macros))
    if names is not None:
        wanted = list(names)
        missing = [n for n in wanted if n not in own]
        if missing:
            raise KeyError(f"{header.name}: no integer macro {', '.join(missing)}")
        own = wanted
    return "".join(f"#define {name} ...\n" for name in own if name.startswith(prefix))


def _split(text: str) -> list[str]:
    """Top-level declarations: up to each `;` at brace and parenthesis depth 0, and each function definition up to
    its body's closing brace."""
    out, depth, start, body = [], 0, 0, False
    for i, ch in enumerate(text):
        if ch in "{(":
            if ch == "{" and depth == 0:
                head = text[start:i].strip()
                body = head.endswith(")") and not head.startswith("typedef")
            depth += 1
        elif ch in "})":
            depth -= 1
            if ch == "}" and depth == 0 and body:
                out.append(text[start:i + 1].strip())
                start, body = i + 1, False
        elif ch == ";" and depth == 0:
            out.append(text[start:i + 1].strip())
            start = i + 1
    return [d for d in out if d]


def _prototype(decl: str) -> str:
    """A function definition as its prototype; any declaration without `static` / `inline`."""
    brace = decl.find("{")
    if brace >= 0 and decl[:brace].rstrip().endswith(")"):
        decl = decl[:brace].rstrip() + ";"
    return _STORAGE.sub("", decl)


def _name(decl: str) -> str | None:
    """The name a declaration declares: a typedef's last identifier, a function's name (prototype or definition)."""
    body = _prototype(decl).rstrip(";").strip()
    if body.startswith("typedef"):
        if body.endswith(")"):  # a function pointer typedef: typedef int (*name)(...)
            m = _POINTER_NAME.search(body)
            return m.group(1) if m else None
        m = _TRAILING_NAME.search(body)
        return m.group(1) if m else None
    if "(" in body and "{" not in body:
        m = _FUNCTION_NAME.search(body)
        return m.group(1) if m else None
    return None


def declared_names(text: str) -> set[str]:
    """What a piece of C (a header, or a cdef string) declares: typedefs, functions, struct tags and `#define`d
    macros."""
    names = {m.group(1) for m in _OBJECT_MACRO.finditer(_COMMENT.sub(" ", text))}
    names |= {m.group(1) for m in re.finditer(r"^[ \t]*#[ \t]*define[ \t]+([A-Za-z_]\w*)\(", text, re.M)}
    for decl in _split(_clean(text)):
        name = _name(decl)
        if name is not None:
            names.add(name)
        tag = re.match(r"typedef\s+(?:struct|union)\s+([A-Za-z_]\w*)|(?:struct|union)\s+([A-Za-z_]\w*)\s*[{;]", decl)
        if tag is not None:
            names.add(tag.group(1) or tag.group(2))
    return names


def _members(body: str) -> list[str]:
    """The member declarations of a struct body (nested struct / union members whole)."""
    return [m.rstrip(";").strip() for m in _split(body)]


def _split_commas(text: str) -> list[str]:
    out, depth, start = [], 0, 0
    for i, ch in enumerate(text):
        if ch in "([{":
            depth += 1
        elif ch in ")]}":
            depth -= 1
        elif ch == "," and depth == 0:
            out.append(text[start:i].strip())
            start = i + 1
    out.append(text[start:].strip())
    return out


def _field_name(declarator: str) -> str:
    m = re.search(r"([A-Za-z_]\w*)\s*(?:\[[^\]]*\]\s*)*$", declarator)
    return m.group(1) if m else ""


def _fields(member: str) -> list[tuple[str, str]]:
    """(field name, its declaration) for each field a member declares: `int64_t a, b[2];` gives two."""
    if "{" in member:  # a nested struct or union: kept whole under the names after its body
        tail = member[member.rfind("}") + 1:]
        return [(_field_name(d), member) for d in _split_commas(tail) if d]
    if "(" in member:  # a function pointer field
        m = _POINTER_NAME.search(member)
        return [(m.group(1) if m else "", member)]
    first, *rest = _split_commas(member)
    m = _DECLARATOR.match(first)
    if m is None:
        return []
    base = m.group(1)
    return [(_field_name(d), f"{base} {d}") for d in [m.group(2), *rest]]


def _cut(decl: str, name: str, keep: Iterable[str]) -> str:
    """The struct typedef `decl` with only the fields `keep` (in the header's order) and `...;`."""
    kept = list(keep)
    open_, close = decl.find("{"), decl.rfind("}")
    if open_ < 0:
        raise KeyError(f"{name} is not a struct with a body")
    fields = [f for member in _members(decl[open_ + 1:close]) for f in _fields(member)]
    missing = [k for k in kept if k not in {n for n, _ in fields}]
    if missing:
        raise KeyError(f"{name}: no field {', '.join(missing)}")
    lines = [f"    {text};" for field, text in fields if field in kept]
    return decl[:open_ + 1] + "\n" + "\n".join([*lines, "    ...;"]) + "\n" + decl[close:]


def _opaque(decl: str, name: str) -> str:
    m = re.match(r"typedef\s+(struct|union)\s+([A-Za-z_]\w*)", decl)
    if m is None:
        raise KeyError(f"{name} is not a tagged struct typedef (an opaque declaration needs the tag)")
    return f"typedef {m.group(1)} {m.group(2)} {name};"


def _sizes(text: str, values: Mapping[str, int]) -> str:
    """Array sizes given by macros (or integer expressions of them) replaced by their values."""
    def size(m: re.Match[str]) -> str:
        inner = m.group(1).strip()
        if inner in ("", "...") or inner.isdigit():
            return m.group(0)
        v = evaluate(inner, values)
        if v is None:
            raise KeyError(f"array size {inner!r} is not an integer macro expression of the headers given")
        return f"[{v}]"
    return _ARRAY_SIZE.sub(size, text)


def declarations(header: Path, names: Iterable[str], macros: Mapping[str, int] | None = None,
                 partial: Mapping[str, Iterable[str]] | None = None, opaque: Iterable[str] = (),
                 extern_python: Iterable[str] = ()) -> str:
    """The named declarations of `header` as cffi cdef text; KeyError naming any name the header lacks.
    `macros`: integer macros for array sizes (default: the header's own; `constants(a, b)` for a size from another
    header). `partial`: struct typedefs of `names` cut down to the fields given and `...;`. `opaque`: tagged struct
    typedefs of `names` declared without their fields. `extern_python`: functions of `names` the cffi module
    defines in Python (`extern "Python"`)."""
    wanted = list(names)
    cut = dict(partial or {})
    hidden, python = set(opaque), set(extern_python)
    values = constants(header) if macros is None else macros
    stray = [n for n in [*cut, *hidden, *python] if n not in wanted]
    if stray:
        raise KeyError(f"{header.name}: {', '.join(stray)} not among the names asked for")
    found: dict[str, str] = {}
    for decl in _split(_clean(header.read_text(encoding="utf-8"))):
        name = _name(decl)
        if name in wanted:
            text = _prototype(decl).replace("NL_PACKED", "")
            if name in cut:
                text = _cut(text, name, cut[name])
            elif name in hidden:
                text = _opaque(text, name)
            if name in python:
                text = 'extern "Python" ' + text
            found[name] = "\n".join(line.rstrip() for line in _sizes(text, values).splitlines())
    missing = [n for n in wanted if n not in found]
    if missing:
        raise KeyError(f"{header.name}: no declaration of {', '.join(missing)}")
    return "\n".join(found[n] for n in sorted(found, key=wanted.index)) + "\n"


__all__ = ["cffi_constants", "constants", "declarations", "declared_names", "evaluate"]
