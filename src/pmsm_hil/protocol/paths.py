"""Repository paths of generated artefacts (valid in a source checkout / editable install)."""

from __future__ import annotations

from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[3]
GENERATED_C_DIR = REPO_ROOT / "firmware_stub" / "generated"
IDS_PY = Path(__file__).resolve().with_name("ids.py")
GOLDEN_JSON = REPO_ROOT / "tests" / "golden" / "frames.json"
GOLDEN_C_HEADER = REPO_ROOT / "firmware_stub" / "tests" / "golden_frames.h"
