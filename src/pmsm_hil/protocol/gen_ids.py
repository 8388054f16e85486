"""Ids from the DBC value tables: the C header `hil_ids.h` and the Python module `src/pmsm_hil/protocol/ids.py`.

Each id family (controller, mode, parameter, status, node, node state) is one VAL_TABLE_ of `hil.dbc`;
`ParamUnit` and `ParamDoc` annotate the parameter ids. A family may have a table of reserved ids
(`ControllerIdReserved`: 255 "external", the label of a foreign firmware's own controller): they are named
in C and Python like the family's ids but lie above them and are not counted in its `*_COUNT`, so arrays
indexed by id (the firmware's controller table) keep their size. Value descriptions (`VALUE_DESCRIPTIONS`:
enable, mirror, switching states, execution time) only name values for DBC tools; no ids are generated
from them (cantools' C codec has `*_CHOICE` macros). Every signal value table (VAL_) must repeat one
family (with its reserved ids) or one value description exactly, and every table must be used by a
signal, so a signal cannot drift from its table. Written and checked by `python -m pmsm_hil.protocol.gen_c`
together with the cantools codec.
"""

from __future__ import annotations

import json
import re
import textwrap
from dataclasses import dataclass
from typing import Any

from cantools.database.can.c_source import camel_to_snake_case

from pmsm_hil.protocol.errors import DatabaseError

GENERATOR = "python -m pmsm_hil.protocol.gen_c"
C_HEADER = "hil_ids.h"


@dataclass(frozen=True, slots=True)
class Family:
    """One id family: its VAL_TABLE_ (also the Python enum's name), C macro prefix and name dict, and
    the VAL_TABLE_ of its reserved ids (above the family's ids, not counted), if it has one."""

    table: str
    c_prefix: str
    names_dict: str
    reserved: str | None = None

    @property
    def reserved_set(self) -> str:
        """Python name of the frozenset of reserved ids ("CONTROLLER_NAMES" -> "RESERVED_CONTROLLER_IDS")."""
        return "RESERVED_" + self.names_dict.removesuffix("_NAMES") + "_IDS"


FAMILIES = (
    Family("ControllerId", "HIL_FW_CTRL_", "CONTROLLER_NAMES", reserved="ControllerIdReserved"),
    Family("Mode", "HIL_FW_MODE_", "MODE_NAMES"),
    Family("ParamId", "HIL_FW_P_", "PARAM_NAMES"),
    Family("Status", "HIL_FW_STATUS_", "STATUS_NAMES"),
    Family("Node", "HIL_FW_NODE_", "NODE_NAMES"),
    Family("NodeState", "HIL_FW_NODE_STATE_", "NODE_STATE_NAMES"),
)
#: annotation table -> (family it annotates, Python dict name)
ANNOTATIONS = {"ParamUnit": ("ParamId", "PARAM_UNITS"), "ParamDoc": ("ParamId", "PARAM_DOCS")}
#: value descriptions for DBC tools (no ids generated): names are printable ASCII text
VALUE_DESCRIPTIONS = ("Enable", "Mirror", "SwitchState3", "ExecTime")
#: Python member names for DBC names that are not identifiers (the C macros keep the DBC spelling)
PY_MEMBER = {"3vmpc": "MPC_3V"}

_NAME = re.compile(r"[a-z0-9]+([_-][a-z0-9]+)*")
_TEXT = re.compile(r"[ -~]*")  # printable ASCII: safe in C comments and Python strings alike


@dataclass(frozen=True, slots=True)
class IdTables:
    """The checked value tables: family -> {id: name} (counted ids), family -> {id: name} (reserved ids,
    empty if none), annotation -> {id: text}, family or value description -> signals using it."""

    families: dict[str, dict[int, str]]
    reserved: dict[str, dict[int, str]]
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


def _check_names(table: str, values: dict[int, str]) -> None:
    for key, name in values.items():
        if not _NAME.fullmatch(name) or _member(name) in ("COUNT",) or _member(name).endswith("_NAME"):
            raise DatabaseError(f"VAL_TABLE_ {table}: value {key} name {name!r} is not a plain lower-case "
                                "name (letters, digits, '_' or '-'; not 'count', not ending in '_name')")


def _printable(table: str, values: dict[int, str]) -> None:
    bad = [k for k, v in values.items() if not _TEXT.fullmatch(v) or "*/" in v]
    if bad:
        raise DatabaseError(f"VAL_TABLE_ {table}: value {bad[0]} has text that is not printable ASCII")


def load_tables(db: Any) -> IdTables:
    """Read and check the id families of a cantools database; raises DatabaseError naming the table."""
    tables = {name: {int(k): str(v) for k, v in table.items()} for name, table in db.dbc.value_tables.items()}
    known = {*(f.table for f in FAMILIES), *(f.reserved for f in FAMILIES if f.reserved), *ANNOTATIONS,
             *VALUE_DESCRIPTIONS}
    unknown = [name for name in tables if name not in known]
    if unknown:
        raise DatabaseError(f"VAL_TABLE_ {unknown[0]} is not known to gen_ids: add it to FAMILIES (ids), "
                            "a family's reserved table or VALUE_DESCRIPTIONS (names for tools only)")
    families: dict[str, dict[int, str]] = {}
    reserved: dict[str, dict[int, str]] = {}
    for fam in FAMILIES:
        values = tables.get(fam.table)
        if not values:
            raise DatabaseError(f"VAL_TABLE_ {fam.table} missing or empty in the DBC")
        extra = tables.get(fam.reserved, {}) if fam.reserved else {}
        if fam.reserved and not extra:
            raise DatabaseError(f"VAL_TABLE_ {fam.reserved} (reserved ids of {fam.table}) missing or empty in the DBC")
        _check_names(fam.table, values)
        _check_names(str(fam.reserved), extra)
        if extra and min(extra) <= max(values):
            raise DatabaseError(f"VAL_TABLE_ {fam.reserved}: reserved id {min(extra)} is not above the ids of "
                                f"{fam.table} (largest {max(values)}), so it would be counted in its *_COUNT")
        if len({_member(n) for n in (*values.values(), *extra.values())}) != len(values) + len(extra):
            raise DatabaseError(f"VAL_TABLE_ {fam.table}: names are not unique")
        families[fam.table] = dict(sorted(values.items()))
        reserved[fam.table] = dict(sorted(extra.items()))
    annotations: dict[str, dict[int, str]] = {}
    for table, (family, _) in ANNOTATIONS.items():
        values = tables.get(table, {})
        if set(values) != set(families[family]):
            raise DatabaseError(f"VAL_TABLE_ {table} must give one text per {family} id")
        _printable(table, values)
        annotations[table] = dict(sorted(values.items()))
    described: dict[str, dict[int, str]] = {}
    for table in VALUE_DESCRIPTIONS:
        if not tables.get(table):
            raise DatabaseError(f"VAL_TABLE_ {table} missing or empty in the DBC")
        _printable(table, tables[table])
        described[table] = tables[table]
    expected = {name: {**values, **reserved[name]} for name, values in families.items()} | described
    users: dict[str, list[str]] = {name: [] for name in expected}
    for msg in db.messages:
        for sig in msg.signals:
            if not sig.choices:
                continue
            choices = {int(k): str(v) for k, v in sig.choices.items()}
            match = [name for name, values in expected.items() if values == choices]
            if not match:
                raise DatabaseError(f"{msg.name}.{sig.name}: its VAL_ table equals no VAL_TABLE_ "
                                    f"({', '.join(expected)}); make it repeat one exactly "
                                    "(an id family with its reserved ids)")
            users[match[0]].append(f"{msg.name}.{sig.name}")
    unused = [name for name, sigs in users.items() if not sigs]
    if unused:
        raise DatabaseError(f"VAL_TABLE_ {unused[0]} is used by no signal")
    return IdTables(families, reserved, annotations, users)


def _signal_names(t: IdTables, family: str) -> str:
    """Distinct signal names using a family ("`code`, `status`")."""
    return ", ".join(dict.fromkeys(f"`{full.split('.')[1]}`" for full in t.users[family]))


def _wrapped_comment(text: str, width: int = 110) -> list[str]:
    """A C block comment of `text` wrapped at `width` columns."""
    out = [(" * " if i else "/* ") + line for i, line in enumerate(textwrap.wrap(text, width - 6))]
    out[-1] += " */"
    return out


def render_c(t: IdTables, frames: list[str]) -> str:
    """The C header of ids: one macro per value, its name string, and a count (largest id + 1); reserved
    ids follow the count, which does not include them; then the lines `frames` (render_frames_c)."""
    out = [
        "/* Ids of the HIL protocol, generated from the VAL_TABLE_ entries of src/pmsm_hil/protocol/hil.dbc by",
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
        for key, name in t.reserved[fam.table].items():
            macro = fam.c_prefix + _member(name)
            rows.append((macro, str(key), f"reserved ({fam.reserved}): not counted in {fam.c_prefix}COUNT"))
            rows.append((macro + "_NAME", json.dumps(name), ""))
        width = max(len(r[0]) for r in rows) + 1
        for macro, value, note in rows:
            line = f"#define {macro:<{width}}{value}"
            out.append(f"{line} /* {note} */" if note else line)
    out += [*frames, "", "#endif", ""]
    return "\n".join(out)


def render_frames_c(db: Any) -> list[str]:
    """HIL_FRAMES(X): X(id, length, target, command) for each message of the DBC in id order, with the id and
    length macros of hil_protocol.h; `target` 1 when its sender is the Target node, `command` 1 for a Command
    frame (Cmd*: every one carries `seq` in bytes 0-1)."""
    out = ["", *_wrapped_comment("Frames of the DBC: HIL_FRAMES(X) expands X(id, length, target, command) for each "
                                 "message in id order (the id and length macros of hil_protocol.h); target: its "
                                 "sender is the Target node; command: a Command frame (Cmd*, `seq` in bytes 0-1)"),
           "#define HIL_FRAMES(X) \\"]
    rows = []
    for msg in sorted(db.messages, key=lambda m: m.frame_id):
        macro = "HIL_PROTOCOL_" + camel_to_snake_case(msg.name).upper()
        target, command = int("Target" in (msg.senders or [])), int(msg.name.startswith("Cmd"))
        rows.append(f"    X({macro}_FRAME_ID, {macro}_LENGTH, {target}, {command})")
    width = max(len(r) for r in rows) + 1
    out += [f"{r:<{width}}\\" for r in rows[:-1]] + [rows[-1]]
    return out


def _py_dict(name: str, enum: str, values: dict[int, str], members: dict[int, str]) -> list[str]:
    out = [f"{name}: dict[{enum}, str] = {{"]
    out += [f"    {enum}.{members[k]}: {json.dumps(v)}," for k, v in values.items()]
    return [*out, "}"]


def render_python(t: IdTables) -> str:
    """The Python module of ids: one IntEnum per family and the DBC names (and parameter units/docs)."""
    out = [
        '"""Shared numbering: controller ids, setpoint modes, config parameters, status codes, nodes.',
        "",
        "Generated from the VAL_TABLE_ entries of src/pmsm_hil/protocol/hil.dbc by",
        f"`{GENERATOR}`; do not edit (CI runs it with --check). The C side is",
        "firmware_stub/generated/hil_ids.h. Parameter values are float32 in the SI units of PARAM_UNITS",
        '("-": dimensionless or a code); PARAM_DOCS says what each parameter is."""',
        "",
        "from __future__ import annotations",
        "",
        "from enum import IntEnum",
    ]
    for fam in FAMILIES:
        values = {**t.families[fam.table], **t.reserved[fam.table]}
        members = {k: py_member(v) for k, v in values.items()}
        out += ["", "", f"class {fam.table}(IntEnum):",
                f'    """Values of {_signal_names(t, fam.table)} in the DBC; names in `{fam.names_dict}`."""', ""]
        out += [f"    {members[k]} = {k}" for k in values]
        out += ["", "", *_py_dict(fam.names_dict, fam.table, values, members)]
        if t.reserved[fam.table]:
            ids = ", ".join(f"{fam.table}.{members[k]}" for k in t.reserved[fam.table])
            out += ["", f"#: reserved ids ({fam.reserved}): named by the protocol, not counted in {fam.c_prefix}COUNT",
                    f"{fam.reserved_set}: frozenset[{fam.table}] = frozenset({{{ids}}})"]
        for table, (family, dict_name) in ANNOTATIONS.items():
            if family == fam.table:
                out += ["", *_py_dict(dict_name, fam.table, t.annotations[table], members)]
    return "\n".join([*out, ""])


def render(db: Any) -> tuple[str, str]:
    """(C header, Python module) of the ids of a cantools database."""
    tables = load_tables(db)
    return render_c(tables, render_frames_c(db)), render_python(tables)
