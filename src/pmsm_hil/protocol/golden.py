"""Golden frame vectors shared by the Python and C tests.

Usage: python -m pmsm_hil.protocol.golden [--check]
Writes tests/golden/frames.json (message -> frames hex + decoded values, both profiles) and
firmware_stub/tests/golden_frames.h (one C check per frame for test_codec.c). `--check` exits 1
if either committed file differs from a fresh generation.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path
from typing import Any

from cantools.database.can.c_source import camel_to_snake_case

from pmsm_hil.protocol import Command, ConfigAck, ConfigParam, Fault, Heartbeat, Measurement, Measurement6, Setpoint
from pmsm_hil.protocol.codec import PROFILES, FrameCodec, decode_message, layout_for_id
from pmsm_hil.protocol.frame import Frame
from pmsm_hil.protocol.layout import FrameLayout
from pmsm_hil.protocol.messages import Message
from pmsm_hil.protocol.paths import GOLDEN_C_HEADER, GOLDEN_JSON

CASES: tuple[tuple[str, Message], ...] = (
    ("meas_nominal", Measurement(1, 1.234, -0.617, -0.617, 1.0, 104.72, 48.0, 0)),
    ("meas_limits", Measurement(65535, -32.768, 32.767, 0.0, 6.2831, -655.36, 655.35, 1)),
    ("meas_saturated_wrapped", Measurement(70000, 40.0, -40.0, 0.0005, -0.5, 700.0, -3.0, 2)),
    ("meas6_nominal", Measurement6(2, 66.7, -33.35, -33.35, 57.76, -57.76, 0.0, 0.5, 157.08, 300.0, 0)),
    ("meas6_saturated_wrapped", Measurement6(65537, 400.0, -400.0, 0.004, 327.67, -327.68, 1.0, 7.0, 1.0, 48.0, 1)),
    ("cmd_six_phase_v3", Command(3, (27, 10), (73205, 26795), 7, 13, 2100, 0)),
    ("cmd_three_states", Command(1, (4, 6, 7), (30000, 20000, 50000), 12, 27, 1234, 0)),
    ("cmd_two_states_limits", Command(65535, (1, 63), (1048575, 0), 255, 255, 2**32 - 1, 6)),
    ("cmd_one_state_clamped", Command(42, (0,), (100000,), 0, 1, 5_000_000_000, 0)),
    ("cmd_mirror_three_states", Command(7, (0, 4, 6), (12500, 20000, 35000), 17, 6, 950, 0, True)),
    ("cmd_mirror_two_states", Command(65534, (7, 6), (1, 99998), 36, 1, 0, 0, True)),
    ("setpoint_speed", Setpoint(True, 0, 104.5, 1)),
    ("setpoint_torque", Setpoint(False, 1, -2.25, 11)),
    ("config_rs", ConfigParam(1, 0.0125)),
    ("config_current_limit", ConfigParam(22, 30.0)),
    ("config_dt_comp", ConfigParam(24, 1.0)),
    ("config_fcs_reading", ConfigParam(25, 96.0)),
    ("config_v3_symmetric", ConfigParam(26, 1.0)),
    ("config_ack_ok", ConfigAck(5, 4.0, 0)),
    ("config_ack_invalid", ConfigAck(200, -1.5, 5)),
    ("heartbeat_host", Heartbeat(0, 2, 17)),
    ("heartbeat_target", Heartbeat(1, 1, 255)),
    ("fault_host", Fault(0, 3, 0x00000101)),
    ("fault_target", Fault(1, 1, 0xDEADBEEF)),
)


def _fields(msg: Message) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for f in dataclasses.fields(msg):
        v = getattr(msg, f.name)
        out[f.name] = list(v) if isinstance(v, tuple) else v
    return out


def _frame_entry(fr: Frame) -> dict[str, Any]:
    lay = layout_for_id(fr.arbitration_id)
    if lay is None:  # pragma: no cover - the codec only emits protocol ids
        raise KeyError(fr.arbitration_id)
    raw = lay.unpack(fr.data)
    phys = {
        s.name: (r * s.scale + s.offset if s.scale != 1.0 or s.offset != 0.0 else r)
        for s, r in zip(lay.signals, raw, strict=True)
    }
    return {
        "id": fr.arbitration_id,
        "dbc": lay.name,
        "is_fd": fr.is_fd,
        "data": fr.data.hex(),
        "raw": {s.name: r for s, r in zip(lay.signals, raw, strict=True)},
        "phys": phys,
    }


def build_vectors() -> dict[str, Any]:
    """The golden vectors as a JSON-ready dict."""
    cases = []
    for profile in PROFILES:
        codec = FrameCodec(profile)
        for name, msg in CASES:
            frames = codec.encode(msg)
            cases.append(
                {
                    "name": name,
                    "profile": profile,
                    "type": type(msg).__name__,
                    "input": _fields(msg),
                    "decoded": _fields(decode_message(frames)),
                    "frames": [_frame_entry(fr) for fr in frames],
                }
            )
    return {"generator": "python -m pmsm_hil.protocol.golden", "dbc": "src/pmsm_hil/protocol/hil.dbc", "cases": cases}


def render_json(vectors: dict[str, Any]) -> str:
    """Stable JSON text."""
    return json.dumps(vectors, indent=1, sort_keys=False) + "\n"


def _c_literal(sig_is_float: bool, value: Any) -> str:
    if sig_is_float:
        return f"{float(value).hex()}f"
    return f"{int(value)}" + ("u" if int(value) >= 0 else "")


def _c_check(idx: int, case: str, entry: dict[str, Any], lay: FrameLayout) -> str:
    snake = camel_to_snake_case(lay.name)
    data = bytes.fromhex(entry["data"])
    lines = [
        f"/* {case}: {lay.name} 0x{lay.frame_id:03X} */",
        f"static int golden_check_{idx}(void)",
        "{",
        f"    static const uint8_t data[{len(data)}] = {{{', '.join(f'0x{b:02x}' for b in data)}}};",
        f"    uint8_t out[{len(data)}];",
        f"    struct hil_protocol_{snake}_t m;",
        "    int fails = 0;",
        f"    if (hil_protocol_{snake}_unpack(&m, data, sizeof data) != 0) {{",
        f'        printf("golden {idx} {case}: {lay.name} unpack failed\\n");',
        "        return 1;",
        "    }",
    ]
    for sig in lay.signals:
        raw = entry["raw"][sig.name]
        lit = _c_literal(sig.is_float, raw)
        ctype = "double" if sig.is_float else "long long"
        lines.append(f'    GOLDEN_EXPECT_EQ("{case}", "{lay.name}.{sig.name}", ({ctype})m.{sig.name}, ({ctype}){lit});')
        if sig.scale != 1.0 or sig.offset != 0.0:
            phys = entry["phys"][sig.name]
            lines.append(
                f'    GOLDEN_EXPECT_NEAR("{case}", "{lay.name}.{sig.name}", '
                f"hil_protocol_{snake}_{sig.name}_decode(m.{sig.name}), {float(phys).hex()}f, "
                f"{abs(sig.scale) * 1e-3 + abs(float(phys)) * 1e-6:.3e}f);"
            )
            lines.append(
                f'    GOLDEN_EXPECT_EQ("{case}", "{lay.name}.{sig.name} encode", '
                f"(long long)hil_protocol_{snake}_{sig.name}_encode({float(phys).hex()}f), "
                f"(long long){lit});"
            )
    lines += [
        f"    if (hil_protocol_{snake}_pack(out, &m, sizeof out) != (int)sizeof out "
        "|| memcmp(out, data, sizeof out) != 0) {",
        f'        printf("golden {idx} {case}: {lay.name} pack differs\\n");',
        "        fails++;",
        "    }",
        "    return fails;",
        "}",
        "",
    ]
    return "\n".join(lines)


def render_c_header(vectors: dict[str, Any]) -> str:
    """C header with one check function per distinct golden frame."""
    out = [
        "/* Golden frames from tests/golden/frames.json.",
        " * Generated by python -m pmsm_hil.protocol.golden; do not edit. */",
        "#ifndef GOLDEN_FRAMES_H",
        "#define GOLDEN_FRAMES_H",
        "",
        "#include <stdint.h>",
        "#include <stdio.h>",
        "#include <string.h>",
        "",
        '#include "hil_protocol.h"',
        "",
        "#define GOLDEN_EXPECT_EQ(case_, field, got, want) do { if ((got) != (want)) { \\",
        '    printf("golden %s: %s = %lld, expected %lld\\n", case_, field, \\',
        "    (long long)(got), (long long)(want)); \\",
        "    fails++; } } while (0)",
        "#define GOLDEN_EXPECT_NEAR(case_, field, got, want, tol) do { \\",
        "    float golden_d_ = (got) - (want); if (golden_d_ > (tol) || golden_d_ < -(tol)) { \\",
        '    printf("golden %s: %s = %.9g, expected %.9g\\n", case_, field, \\',
        "    (double)(got), (double)(want)); \\",
        "    fails++; } } while (0)",
        "",
    ]
    seen: set[tuple[int, str]] = set()
    names = []
    idx = 0
    for case in vectors["cases"]:
        for entry in case["frames"]:
            key = (entry["id"], entry["data"])
            if key in seen:
                continue
            seen.add(key)
            lay = layout_for_id(entry["id"])
            if lay is None:  # pragma: no cover
                raise KeyError(entry["id"])
            label = f"{case['profile']}/{case['name']}"
            out.append(_c_check(idx, label, entry, lay))
            names.append((idx, label, lay.name))
            idx += 1
    out.append("typedef int (*golden_check_fn)(void);")
    out.append("static const struct { const char *name; golden_check_fn fn; } golden_checks[] = {")
    out += [f'    {{"{label} {dbc}", golden_check_{i}}},' for i, label, dbc in names]
    out += ["};", f"#define GOLDEN_CHECK_COUNT {len(names)}", "", "#endif /* GOLDEN_FRAMES_H */", ""]
    return "\n".join(out)


def render() -> dict[Path, str]:
    """Path -> content of both golden artefacts."""
    vectors = build_vectors()
    return {GOLDEN_JSON: render_json(vectors), GOLDEN_C_HEADER: render_c_header(vectors)}


def main(argv: list[str] | None = None) -> int:
    """Command-line entry; returns the exit code."""
    parser = argparse.ArgumentParser(prog="python -m pmsm_hil.protocol.golden", description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="fail if the committed files are stale")
    args = parser.parse_args(argv)
    stale = 0
    for path, text in render().items():
        if args.check:
            if not path.is_file() or path.read_text(encoding="utf-8") != text:
                print(f"stale: {path} (run python -m pmsm_hil.protocol.golden)", file=sys.stderr)
                stale += 1
        else:
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(text, encoding="utf-8")
            print(f"wrote {path}")
    return 1 if stale else 0


if __name__ == "__main__":
    sys.exit(main())
