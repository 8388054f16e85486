"""docs/foxglove_layout.json: valid layout whose panels reference only our MCAP topics and fields."""

from __future__ import annotations

import json
import re
from pathlib import Path

from pmsm_hil.hil.records import PERIOD_DTYPE, TRACE_DTYPE
from pmsm_hil.hil.runlog import topics

LAYOUT = Path(__file__).resolve().parents[2] / "docs" / "foxglove_layout.json"


def _leaves(node: object) -> list[str]:
    if isinstance(node, str):
        return [node]
    assert isinstance(node, dict)
    return _leaves(node["first"]) + _leaves(node["second"])


def test_layout_panels_and_paths() -> None:
    doc = json.loads(LAYOUT.read_text(encoding="utf-8"))
    panels = doc["configById"]
    assert sorted(_leaves(doc["layout"])) == sorted(panels)
    fields = {topics.TOPIC_PERIODS: set(PERIOD_DTYPE.names or ()), topics.TOPIC_TRACE: set(TRACE_DTYPE.names or ())}
    seen = 0
    for cfg in panels.values():
        values = [p["value"] for p in cfg.get("paths", [])]
        if "xAxisPath" in cfg:
            values.append(cfg["xAxisPath"]["value"])
        for value in values:
            m = re.fullmatch(r"(/\w+)\.(\w+)(\[:\])?", value)
            assert m is not None, value
            assert m.group(2) in fields[m.group(1)], value
            seen += 1
        if "topicPath" in cfg:
            assert cfg["topicPath"] == topics.TOPIC_METADATA
    assert seen >= 15
