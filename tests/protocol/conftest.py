"""Fixtures: every link opened through `links` is closed after the test, and open buses are an error."""

from __future__ import annotations

from collections.abc import Callable, Iterator

import pytest

from pmsm_hil.protocol.links import BusLink, open_link


@pytest.fixture
def links() -> Iterator[Callable[[str, str], BusLink]]:
    """Factory opening links that are all closed (and checked closed) at teardown."""
    opened: list[BusLink] = []

    def make(spec: str, role: str = "host") -> BusLink:
        link = open_link(spec, role)  # type: ignore[arg-type]
        opened.append(link)
        return link

    yield make
    for link in opened:
        link.close()
    for link in opened:
        assert link.bus._is_shutdown, f"{link.description} left open"
