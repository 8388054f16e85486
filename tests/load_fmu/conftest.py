"""The fan FMUs of the load-FMU tests, built once per session (FMI 2.0 and 3.0)."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.load_fmu.fan_fmu import build_fan_fmu


@pytest.fixture(scope="session")
def fan_fmus(tmp_path_factory: pytest.TempPathFactory) -> dict[int, Path]:
    """{2: fan_load FMI 2.0 .fmu, 3: FMI 3.0 .fmu}."""
    out = tmp_path_factory.mktemp("fmu")
    return {fmi: build_fan_fmu(out / f"fmi{fmi}", fmi) for fmi in (2, 3)}
