"""The live view's port (``view_relay.py``): clients offering ``foxglove.websocket.v1`` (Lichtblick) are served by
the SDK's server, which alone answers them HTTP 400 (issue 40); the bytes pass unchanged. No ROS: the SDK's server
in this process."""
import asyncio
import json

import pytest
from tornado.httpclient import HTTPClientError
from tornado.websocket import websocket_connect

from seapup_live_view import view_relay
from seapup_live_view.view_relay import HandshakeError, Relay, rewrite_request, rewrite_response

_REQUEST = (b"GET / HTTP/1.1\r\nHost: 127.0.0.1:8765\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
            b"Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n"
            b"sec-websocket-protocol: %s\r\n\r\n")


def test_a_legacy_offer_is_passed_on_as_the_sdk_s_subprotocol_and_answered_in_its_own_name():
    head, answer = rewrite_request(_REQUEST % b"foxglove.websocket.v1")
    assert answer == "foxglove.websocket.v1"
    assert b"Sec-WebSocket-Protocol: foxglove.sdk.v1\r\n" in head and b"websocket.v1" not in head
    assert head.startswith(b"GET / HTTP/1.1\r\nHost: 127.0.0.1:8765\r\n") and head.endswith(b"\r\n\r\n")
    assert b"Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==" in head   # the accept key depends on it alone
    response = (b"HTTP/1.1 101 Switching Protocols\r\nSec-WebSocket-Accept: s3pPLMBiTxaQ9kYGzzhZRbK+xOo=\r\n"
                b"Sec-WebSocket-Protocol: foxglove.sdk.v1\r\n\r\n")
    assert rewrite_response(response, answer) == response.replace(b"foxglove.sdk.v1", b"foxglove.websocket.v1")


@pytest.mark.parametrize("offer", [b"foxglove.sdk.v1", b"foxglove.websocket.v1, foxglove.sdk.v1",
                                   b"foxglove.sdk.v1.1", b"something.else"])
def test_other_offers_pass_untouched(offer):
    head = _REQUEST % offer
    assert rewrite_request(head) == (head, None)
    assert rewrite_response(b"HTTP/1.1 400 Bad Request\r\n\r\n", None) == b"HTTP/1.1 400 Bad Request\r\n\r\n"


def test_a_head_that_is_not_http_is_refused():
    with pytest.raises(HandshakeError, match="malformed header line"):
        rewrite_request(b"GET / HTTP/1.1\r\nno colon here\r\n\r\n")
    with pytest.raises(HandshakeError, match="blank line"):
        rewrite_request(b"GET / HTTP/1.1\r\n")


@pytest.fixture
def served():
    import foxglove
    server = foxglove.start_server(name="relayed", port=0)
    relay = Relay(0, server.port).start()
    yield relay
    relay.stop()
    server.stop()


async def _server_info(port: int, subprotocols):
    connection = await websocket_connect(f"ws://127.0.0.1:{port}", subprotocols=subprotocols)
    try:
        return connection.selected_subprotocol, json.loads(await asyncio.wait_for(connection.read_message(), 20.0))
    finally:
        connection.close()


def test_both_subprotocols_are_served_through_the_relay(served):
    import foxglove
    direct = foxglove.start_server(port=0)
    try:   # the SDK alone refuses the legacy offer (why the relay exists)
        with pytest.raises(HTTPClientError, match="400"):
            asyncio.run(_server_info(direct.port, ["foxglove.websocket.v1"]))
    finally:
        direct.stop()
    for offer in (["foxglove.websocket.v1"], ["foxglove.sdk.v1"]):
        chosen, info = asyncio.run(_server_info(served.port, offer))
        assert chosen == offer[0] and info["op"] == "serverInfo" and info["name"] == "relayed"


def test_a_bad_head_is_answered_400_with_its_reason_and_viewers_are_bounded(served, monkeypatch):
    import socket

    def exchange(data: bytes) -> bytes:
        with socket.create_connection(("127.0.0.1", served.port), timeout=20.0) as s:
            s.sendall(data)
            answer = b""
            while chunk := s.recv(4096):
                answer += chunk
            return answer
    answer = exchange(b"GET / HTTP/1.1\r\n" + b"X: " + b"y" * view_relay.MAX_HEAD_BYTES + b"\r\n\r\n")
    assert answer.startswith(b"HTTP/1.1 400") and b"request head over 16384 bytes" in answer
    monkeypatch.setattr(view_relay, "MAX_CONNECTIONS", 0)
    answer = exchange(_REQUEST % b"foxglove.sdk.v1")
    assert answer.startswith(b"HTTP/1.1 503") and b"0 viewers already connected" in answer
