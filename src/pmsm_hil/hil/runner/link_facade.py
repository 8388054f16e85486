"""What the native loop's links to another process or through Python share: between runs of the C loop they are
the Python link they wrap (`TargetClient` configures the target and sends the Setpoints through them)."""

from __future__ import annotations

from collections.abc import Sequence

from pmsm_hil.protocol.frame import Frame
from pmsm_hil.protocol.links import Link


class LinkFacade:
    """`Link.send` / `poll` / `recv` / `close` passed to the wrapped `link`."""

    link: Link

    def send(self, frames: Sequence[Frame]) -> None:
        """As `Link.send` (Python, between runs of the C loop)."""
        self.link.send(frames)

    def poll(self) -> Frame | None:
        """As `Link.poll`."""
        return self.link.poll()

    def recv(self, timeout_s: float) -> Frame | None:
        """As `Link.recv`."""
        return self.link.recv(timeout_s)

    def close(self) -> None:
        """Close the link (idempotent)."""
        self.link.close()
