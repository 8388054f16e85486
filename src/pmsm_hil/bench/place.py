"""A place leased through labgrid's coordinator with labgrid's own client session (`labgrid.remote.client`, in this
process: one gRPC connection for the whole lease, no `labgrid-client` process per step): a reservation that waits
its turn (as `labgrid-client reserve --wait name=PLACE`: a second lease of one place queues behind the first,
leases of different places proceed at once), the place acquired under the reservation, its resources read (as
`labgrid-client env` gives them), then released and the reservation cancelled."""

from __future__ import annotations

import os
import time
from collections.abc import Awaitable
from types import TracebackType
from typing import Any, TypeVar

from pmsm_hil.bench.errors import BenchError

#: labgrid's default coordinator address (its `LG_COORDINATOR` overrides it)
DEFAULT_COORDINATOR = "127.0.0.1:20408"
#: how often a waiting reservation asks the coordinator whether it was allocated [s]
RESERVATION_POLL_S = 0.25
#: the bound of one request to the coordinator (a lease's wait for its turn has none) [s]
REQUEST_TIMEOUT_S = 120.0

_T = TypeVar("_T")


def coordinator_address(explicit: str | None = None) -> str:
    """The coordinator: `explicit`, else `LG_COORDINATOR`, else labgrid's default."""
    return explicit or os.environ.get("LG_COORDINATOR") or DEFAULT_COORDINATOR


def _labgrid_client() -> Any:
    """labgrid's client module; BenchError when labgrid is not installed."""
    try:
        from labgrid.remote import client
    except ImportError:
        raise BenchError("labgrid is not installed (pip install 'pmsm-hil[bench]')") from None
    return client


class PlaceLease:
    """`with PlaceLease("bench-a") as lease:` waits for the place, acquires it, and releases it on leaving;
    `lease.resources` holds the place's resources as `labgrid-client env` gives them (class -> parameters)."""

    def __init__(self, place: str, coordinator: str | None = None) -> None:
        self.place = place
        self.coordinator = coordinator_address(coordinator)
        self.token: str | None = None
        self.acquired = False
        self.resources: dict[str, dict[str, Any]] = {}
        self._session: Any = None
        self._owned = False

    def _fail(self, what: str, exc: BaseException) -> BenchError:
        details = exc.details() if hasattr(exc, "details") else str(exc)
        return BenchError(f"bench {self.place}: {what} failed: {details or type(exc).__name__} "
                          f"(coordinator {self.coordinator})")

    def _call(self, what: str, coro: Awaitable[_T], timeout: float | None = REQUEST_TIMEOUT_S) -> _T:
        """Run one request on the session's event loop; BenchError naming `what` when it fails."""
        import asyncio

        import grpc

        client = _labgrid_client()
        try:
            return self._session.loop.run_until_complete(asyncio.wait_for(coro, timeout))  # type: ignore[no-any-return]
        except TimeoutError:
            raise BenchError(f"bench {self.place}: {what} took more than {timeout:g} s (coordinator "
                             f"{self.coordinator})") from None
        except (grpc.aio.AioRpcError, client.Error) as exc:
            raise self._fail(what, exc) from None

    def _connect(self) -> None:
        """The client session: the one labgrid's RemotePlace resources of this process use when it is connected to
        this coordinator, else a new one that they will use too. The coordinator takes one client stream per
        connection, and gRPC gives all channels of a process to one address one connection: two sessions of one
        process would be refused."""
        client = _labgrid_client()
        from labgrid.resource.remote import RemotePlaceManager

        manager = RemotePlaceManager.get()
        live = manager.session
        if live is not None and not live.stopping.is_set() and manager.url == self.coordinator:
            self._session, self._owned = live, False
            return
        try:
            self._session = client.start_session(self.coordinator)
        except (client.Error, OSError) as exc:
            raise self._fail("connecting to the coordinator", exc) from None
        self._owned = True
        manager.session, manager.loop, manager.url = self._session, self._session.loop, self.coordinator

    def _pb2(self) -> Any:
        from labgrid.remote.generated import labgrid_coordinator_pb2

        return labgrid_coordinator_pb2

    def __enter__(self) -> PlaceLease:
        self._connect()
        try:
            places = sorted(self._session.places)
            if self.place not in places:
                raise BenchError(f"bench {self.place}: no such place on the coordinator {self.coordinator} (places: "
                                 f"{', '.join(places) or 'none'})")
            self.token = self._reserve()
            self._call("acquire", self._acquire())
            self.acquired = True
            self.resources = self._resources()
        except BaseException:
            self.release()
            raise
        return self

    def _reserve(self) -> str:
        """A reservation of the place (filter name=PLACE), waited for until the coordinator allocated it."""
        pb2, stub = self._pb2(), self._session.stub
        request = pb2.CreateReservationRequest(
            filters={"main": pb2.Reservation.Filter(filter={"name": self.place})}, prio=0.0)
        token = str(self._call("reserve", stub.CreateReservation(request)).reservation.token)
        self.token = token
        from labgrid.remote.common import Reservation, ReservationState

        while True:  # waits its turn: no bound (a session may hold the place for hours)
            res = self._call("reservation poll", stub.PollReservation(pb2.PollReservationRequest(token=token)))
            state = Reservation.from_pb2(res.reservation).state
            if state is ReservationState.waiting:
                time.sleep(RESERVATION_POLL_S)
                continue
            if state not in (ReservationState.allocated, ReservationState.acquired):
                raise BenchError(f"bench {self.place}: reservation {token} ended {state.name} before the place was "
                                 "allocated")
            return token

    async def _acquire(self) -> None:
        await self._session.stub.AcquirePlace(self._pb2().AcquirePlaceRequest(placename=self.place))
        await self._session.sync_with_coordinator()

    def _resources(self) -> dict[str, dict[str, Any]]:
        """The acquired place's resources (class -> parameters, the first of each class)."""
        self._call("reading the place", self._session.sync_with_coordinator())
        try:
            config = self._session.get_target_config(self._session.get_place(self.place))
        except _labgrid_client().Error as exc:
            raise self._fail("reading the place's resources", exc) from None
        found: dict[str, dict[str, Any]] = {}
        for entry in config["resources"]:
            for cls, params in entry.items():
                found.setdefault(str(cls), dict(params or {}))
        return found

    def __exit__(self, kind: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None) -> None:
        self.release()

    def release(self) -> None:
        """Release the place and cancel the reservation (both at most once), then close the session."""
        token, self.token = self.token, None
        session, self._session = self._session, None
        if session is None:
            return
        self._session = session
        try:
            if token is not None:
                try:
                    if self.acquired:
                        self.acquired = False
                        self._call("release", self._release())
                finally:
                    pb2 = self._pb2()
                    self._call("cancel-reservation", session.stub.CancelReservation(
                        pb2.CancelReservationRequest(token=token)))
        finally:
            self._session = None
            if self._owned:
                _close(session)

    async def _release(self) -> None:
        await self._session.stub.ReleasePlace(self._pb2().ReleasePlaceRequest(placename=self.place))
        await self._session.sync_with_coordinator()


def _close(session: Any) -> None:
    """End a client session's stream and close its channel (errors of a coordinator gone already ignored); labgrid's
    RemotePlace resources no longer use it."""
    import contextlib

    from labgrid.resource.remote import RemotePlaceManager

    manager = RemotePlaceManager.get()
    if manager.session is session:
        manager.session = manager.loop = None
    with contextlib.suppress(Exception):
        session.loop.run_until_complete(session.stop())
    with contextlib.suppress(Exception):
        session.loop.run_until_complete(session.close())


def parse_env(text: str) -> dict[str, dict[str, Any]]:
    """The resources of a `labgrid-client env` output (YAML `targets: {NAME: {resources: [...]}}`) as class ->
    parameters (the first of each class)."""
    import yaml

    data = yaml.safe_load(text) or {}
    found: dict[str, dict[str, Any]] = {}
    for target in (data.get("targets") or {}).values():
        for entry in (target or {}).get("resources") or []:
            for cls, params in entry.items():
                found.setdefault(str(cls), dict(params or {}))
    return found
