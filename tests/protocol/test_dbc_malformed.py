"""A malformed hil.dbc is one line naming the file, the line and the message.signal: `load_layouts`
on edited copies, and `hil` itself when the protocol's layouts fail at import (no traceback, exit 2)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from pmsm_hil.protocol.errors import DatabaseError
from pmsm_hil.protocol.layout import DBC_PATH, load_layouts

ORIGINAL = DBC_PATH.read_text(encoding="utf-8")
_SG = " SG_ node : 0|8@1+ (1,0) [0|255] \"\" Target"  # the first signal line (FaultHost.node)


def _line_of(text: str, needle: str) -> int:
    return next(n for n, line in enumerate(text.splitlines(), start=1) if needle in line)


def _edited(tmp_path: Path, old: str, new: str) -> tuple[Path, int]:
    assert old in ORIGINAL
    text = ORIGINAL.replace(old, new, 1)
    path = tmp_path / "hil.dbc"
    path.write_text(text, encoding="utf-8")
    return path, _line_of(text, new.split("\n")[0])


@pytest.mark.parametrize(("old", "new", "needle"), [
    (_SG, _SG.replace("0|8@1+", "0x|8@1+"), "(FaultHost.node): Invalid syntax"),  # a start bit that is no number
    (_SG, _SG.replace("(1,0)", "(abc,0)"), "(FaultHost.node): Invalid syntax"),  # a scale that is no number
    (_SG, _SG.replace("0|8@1+", "60|8@1+"), "FaultHost.node: The signal node does not fit"),  # beyond the frame
    (_SG, _SG.replace("0|8@1+", "4|8@1+"), "are overlapping in message FaultHost"),  # over FaultHost.code
])
def test_a_malformed_dbc_is_one_line_naming_line_and_field(tmp_path: Path, old: str, new: str, needle: str) -> None:
    path, line = _edited(tmp_path, old, new)
    with pytest.raises(DatabaseError) as info:
        load_layouts(path)
    text = str(info.value)
    if "overlapping" in needle:
        line = _line_of(path.read_text(encoding="utf-8"), f" SG_ {text.split('The signals ')[1].split()[0]} ")
    assert "\n" not in text and text.startswith(f"{path} line {line}") and needle in text, text


def test_hil_with_a_malformed_dbc_prints_one_line_exit_2(tmp_path: Path) -> None:
    """`hil run` in a process whose cantools reads the edited copy in place of hil.dbc (and whose compiled layouts
    are from another hil.dbc, as after an edit: the DBC is then parsed): the error raised while the subcommands
    are imported (the codec compiles its layouts then) is the usual one line."""
    bad, line = _edited(tmp_path, _SG, _SG.replace("(1,0)", "(abc,0)"))
    code = (
        "import sys, types, cantools\n"
        "compiled = types.ModuleType('pmsm_hil.protocol.compiled_layouts')\n"
        "compiled.DBC_SHA256, compiled.LAYOUTS = 'the sha256 of hil.dbc before an edit', {}\n"
        "sys.modules[compiled.__name__] = compiled\n"
        "real = cantools.database.load_file\n"
        f"cantools.database.load_file = lambda path, *a, **k: real({str(bad)!r}, *a, **k)\n"
        "from pmsm_hil.app.cli.main import main\n"
        "sys.exit(main(['run']))\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in proc.stderr, proc.stderr
    assert lines[0].startswith(f"hil: error: {DBC_PATH} line {line} (FaultHost.node): Invalid syntax"), lines[0]
