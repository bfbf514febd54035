"""The older Foxglove WebSocket subprotocol for ``pushbot view``: a relay in front of the SDK.

``foxglove-sdk`` (0.30) accepts only the subprotocols ``foxglove.sdk.v1`` and
``foxglove.sdk.v1.1``; clients that offer only ``foxglove.websocket.v1`` (older Foxglove
builds, Lichtblick builds from before December 2025, other ``ws-protocol`` clients) get HTTP
400 from it. Foxglove states that ``foxglove.sdk.v1`` is, for now, the same
protocol as ``foxglove.websocket.v1`` under a new name. :class:`SubprotocolRelay` therefore
listens on the view's public address, accepts any of :data:`ACCEPTED` and relays every frame
unchanged, both ways, to the SDK server on a private loopback port (with the client's
``foxglove.sdk.*`` subprotocol, else ``foxglove.sdk.v1``). A client offering none of them
gets HTTP 400, as from the SDK. One relay task pair per client; a client that disconnects
closes its upstream connection and the other way round.
"""

from __future__ import annotations

import asyncio
import threading
from typing import Any

#: Subprotocols the relay accepts, in the order it prefers them when a client offers several.
ACCEPTED = ("foxglove.sdk.v1", "foxglove.sdk.v1.1", "foxglove.websocket.v1")
#: What the relay speaks to the SDK server for a ``foxglove.websocket.v1`` client.
SDK_SUBPROTOCOL = "foxglove.sdk.v1"
#: Seconds to connect to the SDK server (loopback: immediate unless it is gone).
UPSTREAM_TIMEOUT = 10.0


def upstream_subprotocol(client_subprotocol: str | None) -> str:
    """The subprotocol to ask the SDK server for, given the one the client was granted."""
    if client_subprotocol and client_subprotocol.startswith("foxglove.sdk."):
        return client_subprotocol
    return SDK_SUBPROTOCOL


class SubprotocolRelay:
    """Relays Foxglove WebSocket clients to the SDK server (module docstring).

    Parameters
    ----------
    host : str
        Public address to bind.
    port : int
        Public TCP port (0: a free one; see :attr:`port` after :meth:`start`).
    upstream_port : int
        The SDK server's port on 127.0.0.1.
    """

    def __init__(self, host: str, port: int, upstream_port: int) -> None:
        self.host = host
        self.port = port
        self.upstream_port = upstream_port
        #: Clients relayed so far, by granted subprotocol.
        self.clients: dict[str, int] = {}
        self._loop: asyncio.AbstractEventLoop | None = None
        self._server: Any = None
        self._thread: threading.Thread | None = None
        self._ready = threading.Event()
        self._error: BaseException | None = None
        self._connect: Any = None
        self._closed: Any = Exception

    def start(self) -> int:
        """Bind and serve in a background thread; returns the bound port.

        Raises
        ------
        OSError
            When the address cannot be bound.
        ImportError
            When the ``websockets`` package is missing.
        """
        self._thread = threading.Thread(target=self._run, name="view_relay", daemon=True)
        self._thread.start()
        self._ready.wait()
        if self._error is not None:
            raise self._error
        return self.port

    def _run(self) -> None:
        loop = asyncio.new_event_loop()
        self._loop = loop
        try:
            loop.run_until_complete(self._open())
        except BaseException as exc:  # a bind failure, reported by start()
            self._error = exc
            self._ready.set()
            loop.close()
            return
        self._ready.set()
        try:
            loop.run_forever()
        finally:
            loop.run_until_complete(self._close())
            loop.close()

    async def _open(self) -> None:
        try:  # a pip-only dependency: a one-line error where it is missing
            from websockets.asyncio.client import connect
            from websockets.asyncio.server import serve
            from websockets.exceptions import ConnectionClosed
        except ImportError as exc:
            raise ImportError(f"the websockets package is not installed ({exc}): run make "
                              "venv") from exc

        self._connect, self._closed = connect, ConnectionClosed
        self._server = await serve(self._relay, self.host, self.port, subprotocols=list(ACCEPTED),
                                   max_size=None, compression=None)
        self.port = self._server.sockets[0].getsockname()[1]

    async def _close(self) -> None:
        if self._server is not None:
            self._server.close()
            await self._server.wait_closed()
        tasks = [t for t in asyncio.all_tasks() if t is not asyncio.current_task()]
        for task in tasks:
            task.cancel()
        await asyncio.gather(*tasks, return_exceptions=True)

    async def _relay(self, client: Any) -> None:
        connect, ConnectionClosed = self._connect, self._closed  # noqa: N806 - a class
        granted = client.subprotocol
        self.clients[granted] = self.clients.get(granted, 0) + 1
        try:
            async with connect(f"ws://127.0.0.1:{self.upstream_port}",
                               subprotocols=[upstream_subprotocol(granted)], max_size=None,
                               compression=None, open_timeout=UPSTREAM_TIMEOUT) as upstream:

                async def pipe(source: Any, sink: Any) -> None:
                    try:
                        async for frame in source:
                            await sink.send(frame)
                    except ConnectionClosed:
                        pass

                tasks = [asyncio.create_task(pipe(client, upstream)),
                         asyncio.create_task(pipe(upstream, client))]
                await asyncio.wait(tasks, return_when=asyncio.FIRST_COMPLETED)
                for task in tasks:
                    task.cancel()
        except (OSError, TimeoutError, ConnectionClosed):
            pass  # the SDK server is gone (shutting down): the client's connection ends
        finally:
            await client.close()

    def stop(self) -> None:
        """Close the listening socket and every relayed connection (idempotent)."""
        loop, self._loop = self._loop, None
        if loop is not None and loop.is_running():
            loop.call_soon_threadsafe(loop.stop)
        if self._thread is not None:
            self._thread.join(timeout=10.0)
            self._thread = None
