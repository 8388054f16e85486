"""labgrid's side of a drive bench: the resources (`HilLink`: the host's end of the link to the board as a
`hil run --link` spec — `socketcan:can0,fd=true` on a real bench, `udp:L:R@HOST` on a simulated one;
`HilSimBoard`: a simulated board, a `hil target` process on `target_link`), the drivers (`HilLinkDriver`,
`SimBoardDriver`: flash = start the board process with the image, labgrid's `BootstrapProtocol` as its
`OpenOCDDriver` is on a real bench) and `HilBenchStrategy` (power-cycle, flash, reset, wait for the heartbeat).
Importing this module registers them with labgrid's target factory (`imports: [pmsm_hil.bench.labgrid_parts]` in
an environment file). Needs labgrid (the `bench` extra)."""

from __future__ import annotations

import enum
from typing import Any

import attr
from labgrid.driver import Driver
from labgrid.factory import target_factory
from labgrid.protocol import BootstrapProtocol, PowerProtocol, ResetProtocol
from labgrid.resource import Resource
from labgrid.strategy import Strategy

from pmsm_hil.bench.errors import BoardSilentError
from pmsm_hil.bench.heartbeat import wait_heartbeat
from pmsm_hil.bench.sim_board import SimBoard

#: how long a flashed and reset board may take to answer [s]
HEARTBEAT_TIMEOUT_S = 60.0


@target_factory.reg_resource
@attr.s(eq=False)
class HilLink(Resource):  # type: ignore[misc]
    """The bench PC's end of the link to the board, as a `hil run --link` spec."""

    spec: str = attr.ib(validator=attr.validators.instance_of(str))


@target_factory.reg_resource
@attr.s(eq=False)
class HilSimBoard(Resource):  # type: ignore[misc]
    """A simulated board: a `hil target` process serving `target_link` (the board's end of the link)."""

    target_link: str = attr.ib(validator=attr.validators.instance_of(str))


@target_factory.reg_driver
@attr.s(eq=False)
class HilLinkDriver(Driver):  # type: ignore[misc]
    """Gives the place's link spec (`spec`) to the `hil` runs."""

    bindings = {"link": "HilLink"}  # noqa: RUF012 (labgrid's class attribute)

    @property
    def spec(self) -> str:
        """The `hil run --link` spec of the bench's link."""
        return str(self.link.spec)


@target_factory.reg_driver
@attr.s(eq=False)
class SimBoardDriver(Driver, BootstrapProtocol, ResetProtocol):  # type: ignore[misc]
    """Flashes a simulated board: `load(image)` (re)starts its `hil target` process with the image (a SIL library;
    None: the reference firmware), `reset()` restarts it with the same image."""

    bindings = {"board": "HilSimBoard"}  # noqa: RUF012 (labgrid's class attribute)

    def __attrs_post_init__(self) -> None:
        super().__attrs_post_init__()
        self.sim: SimBoard | None = None
        self.image: str | None = None

    def on_deactivate(self) -> None:
        if self.sim is not None:
            self.sim.stop()

    @Driver.check_active  # type: ignore[untyped-decorator]
    def load(self, filename: str | None = None) -> None:
        if self.sim is None:
            self.sim = SimBoard(str(self.board.target_link), name=str(self.target.name))
        self.image = filename
        self.sim.flash(filename)

    @Driver.check_active  # type: ignore[untyped-decorator]
    def reset(self) -> None:
        self.load(self.image)


class Status(enum.Enum):
    """Where `HilBenchStrategy` has brought the bench."""

    unknown = 0
    off = 1
    ready = 2


@target_factory.reg_driver
@attr.s(eq=False)
class HilBenchStrategy(Strategy):  # type: ignore[misc]
    """`transition("ready")`: power the board on (or cycle it), flash the image (the environment's
    `images: {firmware: PATH}`; a simulated board may have none: the reference firmware), reset it unless the
    flash driver resets itself, and wait for the target's heartbeat on the link (BenchError naming the place
    when none comes: BoardSilentError). `transition("off")`: power off (a simulated board: its process ends)."""

    bindings = {  # noqa: RUF012 (labgrid's class attribute)
        "link": "HilLinkDriver",
        "flash": BootstrapProtocol,
        "power": {PowerProtocol, None},
        "reset": {ResetProtocol, None},
    }
    status: Status = attr.ib(default=Status.unknown)

    def __attrs_post_init__(self) -> None:
        super().__attrs_post_init__()
        self.heartbeat_s: float | None = None

    def image(self) -> str | None:
        """The environment's firmware image, or None."""
        env: Any = self.target.env
        if env is None or "firmware" not in (env.config.get_images() or {}):
            return None
        return str(env.config.get_image_path("firmware"))

    def transition(self, status: str | Status) -> None:
        wanted = status if isinstance(status, Status) else Status[status]
        if wanted is Status.off:
            if self.power is not None:
                self.target.activate(self.power)
                self.power.off()
            self.target.deactivate(self.flash)
        elif wanted is Status.ready:
            self._ready()
        self.status = wanted

    def _ready(self) -> None:
        if self.power is not None:
            self.target.activate(self.power)
            self.power.cycle()
        self.target.activate(self.flash)
        self.flash.load(self.image())
        if self.reset is not None and self.reset is not self.flash:
            self.target.activate(self.reset)
            self.reset.reset()
        self.target.activate(self.link)
        self.heartbeat_s = wait_heartbeat(self.link.spec, HEARTBEAT_TIMEOUT_S)
        if self.heartbeat_s is None:
            raise BoardSilentError(f"bench {self.target.name}: no heartbeat from the board on {self.link.spec} within "
                             f"{HEARTBEAT_TIMEOUT_S:g} s of flashing")
