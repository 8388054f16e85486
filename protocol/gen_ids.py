"""Ids from the DBC value tables: the C header `hil_ids.h` and the Python module `protocol/ids.py`.

Each id family (controller, mode, parameter, status, node, node state) is one VAL_TABLE_ of `hil.dbc`;
`ParamUnit` and `ParamDoc` annotate the parameter ids. Every signal value table (VAL_) must repeat one
family exactly, and every family must be used by a signal, so a signal cannot drift from its family.
Written and checked by `python -m pmsm_hil.protocol.gen_c` together with the cantools codec.
"""

from __future__ import annotations

import json
import re
import textwrap
from dataclasses import dataclass
from typing import Any

from pmsm_hil.protocol.errors import DatabaseError

GENERATOR = "python -m pmsm_hil.protocol.gen_c"
C_HEADER = "hil_ids.h"


@dataclass(frozen=True, slots=True)
class Family:
    """One id family: its VAL_TABLE_ (also the Python enum's name), C macro prefix and name dict."""

    table: str
    c_prefix: str
    names_dict: str


FAMILIES = (
    Family("ControllerId", "HIL_FW_CTRL_", "CONTROLLER_NAMES"),
    Family("Mode", "HIL_FW_MODE_", "MODE_NAMES"),
    Family("ParamId", "HIL_FW_P_", "PARAM_NAMES"),
    Family("Status", "HIL_FW_STATUS_", "STATUS_NAMES"),
    Family("Node", "HIL_FW_NODE_", "NODE_NAMES"),
    Family("NodeState", "HIL_FW_NODE_STATE_", "NODE_STATE_NAMES"),
)
#: annotation table -> (family it annotates, Python dict name)
ANNOTATIONS = {"ParamUnit": ("ParamId", "PARAM_UNITS"), "ParamDoc": ("ParamId", "PARAM_DOCS")}
#: Python member names for DBC names that are not identifiers (the C macros keep the DBC spelling)
PY_MEMBER = {"3vmpc": "MPC_3V"}

_NAME = re.compile(r"[a-z0-9]+([_-][a-z0-9]+)*")
_TEXT = re.compile(r"[ -~]*")  # printable ASCII: safe in C comments and Python strings alike


@dataclass(frozen=True, slots=True)
class IdTables:
    """The checked value tables: family -> {id: name}, annotation -> {id: text}, family -> signals."""

    families: dict[str, dict[int, str]]
    annotations: dict[str, dict[int, str]]
    users: dict[str, list[str]]


def _member(name: str) -> str:
    """C macro suffix of a DBC name ("fcs-mpc-1" -> "FCS_MPC_1")."""
    return name.upper().replace("-", "_")


def py_member(name: str) -> str:
    """Python enum member of a DBC name; names starting with a digit need a PY_MEMBER entry."""
    member = PY_MEMBER.get(name, _member(name))
    if not member.isidentifier():
        raise DatabaseError(f"value name {name!r} is not a Python identifier: add it to gen_ids.PY_MEMBER")
    return member


def load_tables(db: Any) -> IdTables:
    """Read and check the id families of a cantools database; raises DatabaseError naming the table."""
    tables = {name: {int(k): str(v) for k, v in table.items()} for name, table in db.dbc.value_tables.items()}
    families: dict[str, dict[int, str]] = {}
    for fam in FAMILIES:
        values = tables.get(fam.table)
        if not values:
            raise DatabaseError(f"VAL_TABLE_ {fam.table} missing or empty in the DBC")
        for key, name in values.items():
            if not _NAME.fullmatch(name) or _member(name) in ("COUNT",) or _member(name).endswith("_NAME"):
                raise DatabaseError(f"VAL_TABLE_ {fam.table}: value {key} name {name!r} is not a plain lower-case "
                                    "name (letters, digits, '_' or '-'; not 'count', not ending in '_name')")
        if len({_member(n) for n in values.values()}) != len(values):
            raise DatabaseError(f"VAL_TABLE_ {fam.table}: names are not unique")
        families[fam.table] = dict(sorted(values.items()))
    annotations: dict[str, dict[int, str]] = {}
    for table, (family, _) in ANNOTATIONS.items():
        values = tables.get(table, {})
        if set(values) != set(families[family]):
            raise DatabaseError(f"VAL_TABLE_ {table} must give one text per {family} id")
        bad = [k for k, v in values.items() if not _TEXT.fullmatch(v) or "*/" in v]
        if bad:
            raise DatabaseError(f"VAL_TABLE_ {table}: value {bad[0]} has text that is not printable ASCII")
        annotations[table] = dict(sorted(values.items()))
    users: dict[str, list[str]] = {fam.table: [] for fam in FAMILIES}
    for msg in db.messages:
        for sig in msg.signals:
            if not sig.choices:
                continue
            choices = {int(k): str(v) for k, v in sig.choices.items()}
            match = [name for name, values in families.items() if values == choices]
            if not match:
                raise DatabaseError(f"{msg.name}.{sig.name}: its VAL_ table equals no id family "
                                    f"({', '.join(families)}); make it repeat the VAL_TABLE_ exactly")
            users[match[0]].append(f"{msg.name}.{sig.name}")
    unused = [name for name, sigs in users.items() if not sigs]
    if unused:
        raise DatabaseError(f"VAL_TABLE_ {unused[0]} is used by no signal")
    return IdTables(families, annotations, users)


def _signal_names(t: IdTables, family: str) -> str:
    """Distinct signal names using a family ("`code`, `status`")."""
    return ", ".join(dict.fromkeys(f"`{full.split('.')[1]}`" for full in t.users[family]))


def _wrapped_comment(text: str, width: int = 110) -> list[str]:
    """A C block comment of `text` wrapped at `width` columns."""
    out = [(" * " if i else "/* ") + line for i, line in enumerate(textwrap.wrap(text, width - 6))]
    out[-1] += " */"
    return out


def render_c(t: IdTables) -> str:
    """The C header of ids: one macro per value, its name string, and a count (largest id + 1)."""
    out = [
        "/* Ids of the HIL protocol, generated from the VAL_TABLE_ entries of protocol/hil.dbc by",
        f" * {GENERATOR}. Do not edit: change the DBC and regenerate (CI checks with --check). */",
        "#ifndef HIL_IDS_H",
        "#define HIL_IDS_H",
    ]
    units, docs = t.annotations["ParamUnit"], t.annotations["ParamDoc"]
    for fam in FAMILIES:
        values = t.families[fam.table]
        out += ["", *_wrapped_comment(f"{fam.table}: {', '.join(t.users[fam.table])}")]
        rows: list[tuple[str, str, str]] = []
        for key, name in values.items():
            macro = fam.c_prefix + _member(name)
            note = f"{docs[key]} [{units[key]}]" if fam.table == "ParamId" else ""
            rows.append((macro, str(key), note))
            rows.append((macro + "_NAME", json.dumps(name), ""))
        rows.append((fam.c_prefix + "COUNT", str(max(values) + 1), "largest id + 1 (size of arrays indexed by id)"))
        width = max(len(r[0]) for r in rows) + 1
        for macro, value, note in rows:
            line = f"#define {macro:<{width}}{value}"
            out.append(f"{line} /* {note} */" if note else line)
    out += ["", "#endif", ""]
    return "\n".join(out)


def _py_dict(name: str, enum: str, values: dict[int, str], members: dict[int, str]) -> list[str]:
    out = [f"{name}: dict[{enum}, str] = {{"]
    out += [f"    {enum}.{members[k]}: {json.dumps(v)}," for k, v in values.items()]
    return [*out, "}"]


def render_python(t: IdTables) -> str:
    """The Python module of ids: one IntEnum per family and the DBC names (and parameter units/docs)."""
    out = [
        '"""Shared numbering: controller ids, setpoint modes, config parameters, status codes, nodes.',
        "",
        "Generated from the VAL_TABLE_ entries of protocol/hil.dbc by",
        f"`{GENERATOR}`; do not edit (CI runs it with --check). The C side is",
        "firmware_stub/generated/hil_ids.h. Parameter values are float32 in the SI units of PARAM_UNITS",
        '("-": dimensionless or a code); PARAM_DOCS says what each parameter is."""',
        "",
        "from __future__ import annotations",
        "",
        "from enum import IntEnum",
    ]
    for fam in FAMILIES:
        values = t.families[fam.table]
        members = {k: py_member(v) for k, v in values.items()}
        out += ["", "", f"class {fam.table}(IntEnum):",
                f'    """Values of {_signal_names(t, fam.table)} in the DBC; names in `{fam.names_dict}`."""', ""]
        out += [f"    {members[k]} = {k}" for k in values]
        out += ["", "", *_py_dict(fam.names_dict, fam.table, values, members)]
        for table, (family, dict_name) in ANNOTATIONS.items():
            if family == fam.table:
                out += ["", *_py_dict(dict_name, fam.table, t.annotations[table], members)]
    return "\n".join([*out, ""])


def render(db: Any) -> tuple[str, str]:
    """(C header, Python module) of the ids of a cantools database."""
    tables = load_tables(db)
    return render_c(tables), render_python(tables)
