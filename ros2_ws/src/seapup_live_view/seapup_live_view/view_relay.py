"""The live view's port: a byte relay in front of the Foxglove server that also answers ``foxglove.websocket.v1``.

The ``foxglove-sdk`` server (0.30.x) accepts only the WebSocket subprotocols ``foxglove.sdk.v1`` and
``foxglove.sdk.v1.1``: a client offering only ``foxglove.websocket.v1`` (the ws-protocol's name, which Lichtblick
and older Foxglove clients offer) gets HTTP 400 "Missing expected sec-websocket-protocol header", and
``start_server`` has no option to change that. The messages are the ws-protocol's either way (the same JSON ops
and binary opcodes), so the view serves its port through this relay: the client's upgrade request is passed to the
SDK's server (on a private port of 127.0.0.1) with ``foxglove.websocket.v1`` replaced by ``foxglove.sdk.v1``, the
server's ``101`` answer is passed back naming the subprotocol the client offered, and from then on the bytes flow
unchanged both ways. A client offering ``foxglove.sdk.v1`` (or ``v1.1``) is passed through untouched.

Bounded: a request head of at most :data:`MAX_HEAD_BYTES` within :data:`HANDSHAKE_TIMEOUT` seconds, at most
:data:`MAX_CONNECTIONS` viewers at once (the next is answered 503), and at most one read buffer per direction
(:data:`CHUNK_BYTES`) held per connection: a viewer that stops reading stops the relay reading the server for it,
so the server's own bounded per-client queue (which drops the oldest messages) takes the backlog, as it does for
a direct client.
"""
from __future__ import annotations

import asyncio
import socket
import threading

__all__ = ["NATIVE_SUBPROTOCOLS", "LEGACY_SUBPROTOCOL", "MAX_HEAD_BYTES", "MAX_CONNECTIONS", "HANDSHAKE_TIMEOUT",
           "CHUNK_BYTES", "HandshakeError", "rewrite_request", "rewrite_response", "Relay"]

#: The subprotocols the SDK's server speaks (the first is the one a legacy client is given).
NATIVE_SUBPROTOCOLS = ("foxglove.sdk.v1", "foxglove.sdk.v1.1")
#: The ws-protocol's subprotocol, which Lichtblick and older Foxglove clients offer.
LEGACY_SUBPROTOCOL = "foxglove.websocket.v1"
#: The largest HTTP request or response head relayed [bytes] (a browser's upgrade request is under 2 KiB).
MAX_HEAD_BYTES = 16384
#: Viewers served at once.
MAX_CONNECTIONS = 16
#: Wall seconds a client has to send its upgrade request (and the server to answer it).
HANDSHAKE_TIMEOUT = 10.0
#: Bytes read at a time from either side.
CHUNK_BYTES = 65536

_PROTOCOL_HEADER = b"sec-websocket-protocol"


class HandshakeError(ValueError):
    """An HTTP head the relay cannot pass on (one line)."""


def _split(head: bytes) -> tuple[bytes, list[tuple[bytes, bytes]]]:
    """An HTTP head (ending in a blank line) as its start line and its (name, value) header lines."""
    if not head.endswith(b"\r\n\r\n"):
        raise HandshakeError("the HTTP head does not end in a blank line")
    start, *lines = head[:-4].split(b"\r\n")
    headers = []
    for line in lines:
        name, colon, value = line.partition(b":")
        if not colon:
            raise HandshakeError(f"malformed header line {line[:40]!r}")
        headers.append((name, value.strip()))
    return start, headers


def _join(start: bytes, headers: list[tuple[bytes, bytes]]) -> bytes:
    return b"\r\n".join([start, *(name + b": " + value for name, value in headers)]) + b"\r\n\r\n"


def _offered(headers) -> list[str]:
    return [p.strip().decode("latin-1") for name, value in headers if name.strip().lower() == _PROTOCOL_HEADER
            for p in value.split(b",") if p.strip()]


def rewrite_request(head: bytes) -> tuple[bytes, str | None]:
    """A client's request head as the SDK's server must see it, and the subprotocol to answer with.

    Parameters
    ----------
    head : bytes
        The request line and headers up to and including the blank line.

    Returns
    -------
    (bytes, str or None)
        The head to send to the server, and ``LEGACY_SUBPROTOCOL`` when the client offered it and none of
        :data:`NATIVE_SUBPROTOCOLS` (its ``Sec-WebSocket-Protocol`` then offers ``foxglove.sdk.v1`` instead);
        otherwise ``head`` unchanged and None (the server answers as it would a direct client).

    Raises
    ------
    HandshakeError
        The head is not HTTP (no blank line at its end, a header line without a colon).
    """
    start, headers = _split(head)
    offered = _offered(headers)
    if any(p in NATIVE_SUBPROTOCOLS for p in offered) or LEGACY_SUBPROTOCOL not in offered:
        return head, None
    headers = [(n, v) for n, v in headers if n.strip().lower() != _PROTOCOL_HEADER]
    headers.append((b"Sec-WebSocket-Protocol", NATIVE_SUBPROTOCOLS[0].encode()))
    return _join(start, headers), LEGACY_SUBPROTOCOL


def rewrite_response(head: bytes, answer: str | None) -> bytes:
    """The server's response head as the client must see it: its subprotocol renamed ``answer`` (if given)."""
    if answer is None:
        return head
    start, headers = _split(head)
    return _join(start, [(n, answer.encode() if n.strip().lower() == _PROTOCOL_HEADER else v) for n, v in headers])


def _refusal(status: str, reason: str) -> bytes:
    body = (reason + "\n").encode()
    return (f"HTTP/1.1 {status}\r\nContent-Type: text/plain\r\nContent-Length: {len(body)}\r\n"
            f"Connection: close\r\n\r\n").encode() + body


class Relay:
    """The relay on 127.0.0.1:``port`` to the server on 127.0.0.1:``upstream_port``, on its own thread.

    Parameters
    ----------
    port : int
        The public port (0: any free port, then :attr:`port`). Bound with address reuse, as the SDK's own
        server binds (a port whose last connection lingers in TIME_WAIT is free again at once).
    upstream_port : int
        The SDK server's port.

    Raises
    ------
    OSError
        The port cannot be bound (in use): raised by :meth:`start`.
    """

    def __init__(self, port: int, upstream_port: int):
        self._requested, self.upstream_port = int(port), int(upstream_port)
        self.port: int | None = None
        self.connections = 0
        self._loop = asyncio.new_event_loop()
        self._server = None
        self._thread = threading.Thread(target=self._loop.run_forever, name="view-relay", daemon=True)

    def start(self) -> "Relay":
        """Bind and serve (returns once the port is bound; raises its OSError if it cannot be)."""
        self._thread.start()
        self._server = asyncio.run_coroutine_threadsafe(self._listen(), self._loop).result()
        self.port = self._server.sockets[0].getsockname()[1]
        return self

    async def _listen(self):
        return await asyncio.start_server(self._serve, "127.0.0.1", self._requested, reuse_address=True,
                                          limit=MAX_HEAD_BYTES, family=socket.AF_INET)

    def stop(self) -> None:
        """Close the port and every connection; end the thread."""
        if not self._thread.is_alive():
            return

        async def close():
            if self._server is not None:
                self._server.close()
            tasks = [t for t in asyncio.all_tasks() if t is not asyncio.current_task()]
            for task in tasks:
                task.cancel()
            await asyncio.gather(*tasks, return_exceptions=True)   # each closes its sockets
        try:
            asyncio.run_coroutine_threadsafe(close(), self._loop).result(5.0)
        finally:
            self._loop.call_soon_threadsafe(self._loop.stop)
            self._thread.join(5.0)

    async def _serve(self, client_reader, client_writer) -> None:
        if self.connections >= MAX_CONNECTIONS:
            await _refuse(client_reader, client_writer, "503 Service Unavailable",
                          f"{MAX_CONNECTIONS} viewers already connected")
            return
        self.connections += 1
        server_writer = None
        try:
            try:
                head = await asyncio.wait_for(client_reader.readuntil(b"\r\n\r\n"), HANDSHAKE_TIMEOUT)
                request, answer = rewrite_request(head)
            except (asyncio.LimitOverrunError, asyncio.IncompleteReadError, asyncio.TimeoutError, HandshakeError,
                    ValueError) as exc:
                reason = f"request head over {MAX_HEAD_BYTES} bytes" if isinstance(exc, asyncio.LimitOverrunError) \
                    else str(exc) or "no complete request head"
                await _refuse(client_reader, client_writer, "400 Bad Request", reason)
                return
            server_reader, server_writer = await asyncio.open_connection("127.0.0.1", self.upstream_port,
                                                                         limit=MAX_HEAD_BYTES)
            server_writer.write(request)
            response = await asyncio.wait_for(server_reader.readuntil(b"\r\n\r\n"), HANDSHAKE_TIMEOUT)
            client_writer.write(rewrite_response(response, answer))
            await asyncio.gather(_pipe(client_reader, server_writer), _pipe(server_reader, client_writer))
        except (OSError, asyncio.IncompleteReadError, asyncio.LimitOverrunError, asyncio.TimeoutError,
                HandshakeError, ValueError):
            pass   # a side went away: both are closed below
        finally:
            self.connections -= 1
            for writer in (client_writer, server_writer):
                if writer is not None:
                    await _close(writer)


async def _pipe(reader, writer) -> None:
    """Copy until end of stream; the writer's drain holds the reader back while the other side does not read."""
    try:
        while True:
            data = await reader.read(CHUNK_BYTES)
            if not data:
                break
            writer.write(data)
            await writer.drain()
    finally:
        writer.close()   # the other side sees the end, and its pipe ends too


async def _refuse(reader, writer, status: str, reason: str) -> None:
    """Answer ``status`` and end the connection so that the client reads the answer: half-close, then discard
    what the client still sends (at most one chunk, for a second). Closing a socket with unread input makes the
    kernel send a reset, which can reach the client before the answer does."""
    writer.write(_refusal(status, reason))
    try:
        if writer.can_write_eof():
            writer.write_eof()
        await asyncio.wait_for(reader.read(CHUNK_BYTES), 1.0)
    except (OSError, asyncio.TimeoutError, asyncio.IncompleteReadError, asyncio.LimitOverrunError):
        pass
    await _close(writer)


async def _close(writer) -> None:
    try:
        writer.close()
        await asyncio.wait_for(writer.wait_closed(), 1.0)
    except (OSError, asyncio.TimeoutError, asyncio.CancelledError):
        pass
