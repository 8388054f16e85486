"""Compare presets written to tmp_path for the compare tests: load, run, or expect a named-key error."""

from __future__ import annotations

from pathlib import Path

import pytest

from pmsm_hil.app.compare import ComparePreset, CompareResult, load_preset, run_preset
from pmsm_hil.hil.errors import InputFileError


def preset_file(tmp_path: Path, text: str, name: str = "preset.toml") -> Path:
    """Write the TOML `text` to tmp_path/`name` and return the path."""
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def load_text(tmp_path: Path, text: str) -> ComparePreset:
    """Load the preset TOML `text` through a file, as `hil compare --preset FILE` does."""
    return load_preset(str(preset_file(tmp_path, text)))


def run_text(tmp_path: Path, text: str) -> CompareResult:
    """Load and run the preset TOML `text` (keep its settle_s/duration_s short)."""
    return run_preset(load_text(tmp_path, text))


def assert_rejected(tmp_path: Path, text: str, match: str) -> None:
    """Loading the preset TOML `text` raises InputFileError whose message matches `match`."""
    with pytest.raises(InputFileError, match=match):
        load_text(tmp_path, text)
