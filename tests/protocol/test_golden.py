"""Golden vectors: the committed JSON matches the codec; generated artefacts are not stale."""

from __future__ import annotations

import json
from typing import Any

import pytest

from pmsm_hil.protocol import gen_c, golden
from pmsm_hil.protocol.codec import FrameCodec, decode_message
from pmsm_hil.protocol.frame import Frame
from pmsm_hil.protocol.layout import load_database
from pmsm_hil.protocol.messages import Command, Measurement
from pmsm_hil.protocol.paths import GENERATED_C_DIR, GOLDEN_JSON

VECTORS: dict[str, Any] = json.loads(GOLDEN_JSON.read_text(encoding="utf-8"))
TYPES = {cls.__name__: cls for cls in golden.Message.__args__}  # type: ignore[attr-defined]


def _message(case: dict[str, Any], key: str) -> Any:
    fields = {k: tuple(v) if isinstance(v, list) else v for k, v in case[key].items()}
    return TYPES[case["type"]](**fields)


def test_every_message_type_and_profile_covered() -> None:
    seen = {(c["type"], c["profile"]) for c in VECTORS["cases"]}
    assert seen == {(t, p) for t in TYPES for p in ("can", "canfd")}


@pytest.mark.parametrize("case", VECTORS["cases"], ids=lambda c: f"{c['profile']}-{c['name']}")
def test_golden_case(case: dict[str, Any]) -> None:
    frames = FrameCodec(case["profile"]).encode(_message(case, "input"))
    assert [(f.arbitration_id, f.data.hex(), f.is_fd) for f in frames] == [
        (e["id"], e["data"], e["is_fd"]) for e in case["frames"]
    ]
    back = decode_message([Frame(e["id"], bytes.fromhex(e["data"]), e["is_fd"]) for e in case["frames"]])
    assert back == _message(case, "decoded")
    db = load_database()
    for e in case["frames"]:
        theirs = db.get_message_by_frame_id(e["id"]).decode(bytes.fromhex(e["data"]), decode_choices=False)
        assert theirs == pytest.approx(e["phys"], rel=1e-12)


def test_saturated_case_documents_policy() -> None:
    case = next(c for c in VECTORS["cases"] if c["name"] == "meas_saturated_wrapped")
    assert case["decoded"]["i_a"] == 32.767 and case["decoded"]["seq"] == 70000 - 65536
    cmd = next(c for c in VECTORS["cases"] if c["name"] == "cmd_one_state_clamped")
    assert cmd["decoded"]["exec_time_ns"] == 2**32 - 1
    assert isinstance(_message(cmd, "decoded"), Command)
    assert isinstance(_message(case, "decoded"), Measurement)


def test_golden_files_not_stale() -> None:
    for path, text in golden.render().items():
        assert path.read_text(encoding="utf-8") == text, f"{path} stale: run python -m pmsm_hil.protocol.golden"


def test_generated_c_not_stale() -> None:
    assert gen_c.stale_files(GENERATED_C_DIR) == []
    assert gen_c.main(["--check"]) == 0


def test_gen_c_check_detects_stale(tmp_path: Any) -> None:
    gen_c.write(tmp_path)
    assert gen_c.main(["--check", "--output-dir", str(tmp_path)]) == 0
    (tmp_path / "hil_protocol.c").write_text("/* edited */\n", encoding="utf-8")
    assert gen_c.main(["--check", "--output-dir", str(tmp_path)]) == 1
