"""The frame layouts compiled to Python (`compiled_layouts.py`, written by `python -m pmsm_hil.protocol.gen_c`) are
the layouts `parse_layouts` compiles from hil.dbc with cantools, field for field and bit for bit; `load_layouts`
takes them only while hil.dbc is the file they were generated from; and `hil run` then imports no cantools."""

from __future__ import annotations

import random
import struct
import subprocess
import sys
from pathlib import Path

import pytest

from pmsm_hil.protocol import compiled_layouts, gen_c, gen_layouts
from pmsm_hil.protocol.layout import DBC_PATH, FrameLayout, dbc_sha256, load_layouts, parse_layouts

PARSED = parse_layouts(DBC_PATH)


def _raw_values(lay: FrameLayout, rng: random.Random) -> list[int | float]:
    """Random raw values over each signal's whole range (floats: float32-exact)."""
    out: list[int | float] = []
    for s in lay.signals:
        if s.is_float:
            v = rng.uniform(-1e6, 1e6)
            out.append(struct.unpack("<f", struct.pack("<f", v))[0] if s.length == 32 else v)
        else:
            out.append(rng.randint(s.raw_min, s.raw_max))
    return out


def _same(a: tuple[object, ...], b: tuple[object, ...]) -> bool:
    """Equal element by element, NaN equal to NaN (all-ones bytes are a NaN float)."""
    return len(a) == len(b) and all(x == y or (x != x and y != y) for x, y in zip(a, b, strict=True))


def test_the_compiled_layouts_are_the_parsed_ones() -> None:
    assert dbc_sha256(DBC_PATH) == compiled_layouts.DBC_SHA256
    assert list(compiled_layouts.LAYOUTS) == list(PARSED)
    rng = random.Random(7)
    for name, parsed in PARSED.items():
        built = compiled_layouts.LAYOUTS[name]
        assert (built.name, built.frame_id, built.length, built.is_fd, built.signals, built.struct_format,
                built.senders) == (parsed.name, parsed.frame_id, parsed.length, parsed.is_fd, parsed.signals,
                                   parsed.struct_format, parsed.senders), name
        for _ in range(200):
            raw = _raw_values(parsed, rng)
            data = parsed.pack(*raw)
            assert built.pack(*raw) == data, (name, raw)
            assert built.unpack(data) == parsed.unpack(data) == tuple(raw), (name, raw)
        extremes = bytes([0xFF] * parsed.length), bytes(parsed.length), rng.randbytes(parsed.length)
        for data in extremes:
            assert _same(built.unpack(data), parsed.unpack(data)), (name, data.hex())


def test_load_layouts_takes_them_for_an_unchanged_dbc_only(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    assert load_layouts.__wrapped__(DBC_PATH) == compiled_layouts.LAYOUTS
    monkeypatch.setattr(compiled_layouts, "DBC_SHA256", "0" * 64)  # hil.dbc edited since the generation
    reparsed = load_layouts.__wrapped__(DBC_PATH)
    assert reparsed is not compiled_layouts.LAYOUTS and reparsed.keys() == PARSED.keys()
    assert all(reparsed[n].pack is not compiled_layouts.LAYOUTS[n].pack for n in reparsed)
    copy = tmp_path / "hil.dbc"
    copy.write_bytes(DBC_PATH.read_bytes())
    other = load_layouts.__wrapped__(copy)  # another file is always parsed
    assert other.keys() == PARSED.keys() and other["MeasA"].pack is not compiled_layouts.LAYOUTS["MeasA"].pack


def test_a_stale_compiled_module_fails_the_check(tmp_path: Path) -> None:
    ids_py = tmp_path / "ids.py"
    gen_c.write(tmp_path, ids_py)
    compiled = tmp_path / "compiled_layouts.py"
    assert compiled.read_text(encoding="utf-8") == gen_layouts.render(DBC_PATH)
    assert gen_c.stale_files(tmp_path, ids_py) == []
    compiled.write_text(compiled.read_text(encoding="utf-8").replace("'<Hhhh'", "'<Hhhi'"), encoding="utf-8")
    assert gen_c.stale_files(tmp_path, ids_py) == [str(compiled)]


def test_hil_run_imports_neither_cantools_nor_the_dbc() -> None:
    code = ("import sys\nimport pmsm_hil.app.cli.run\nimport pmsm_hil.protocol.links.shared_bus as s\n"
            "assert s.target_ids() and s.command_ids()\n"
            "print(sorted(m for m in sys.modules if m.split('.')[0] == 'cantools'))\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0 and proc.stdout.strip() == "[]", proc.stdout + proc.stderr
