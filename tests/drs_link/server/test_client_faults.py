"""A server whose answer breaks off, stalls or does not parse: the client says so as a ``LinkError``.

A console's worker says a ``LinkError`` to the operator; a bare ``TimeoutError``, ``IncompleteRead`` or
msgspec error was not one, and a Sync whose answer broke off left "syncing data…" as its last word. The
server here is a real Unix socket answering real HTTP, badly on purpose."""

from __future__ import annotations

import socket
import threading
from collections.abc import Iterator
from pathlib import Path

import pytest

from drs_link.errors import LinkError, RefusedError
from drs_link.server import Client

CHUNKED = b"HTTP/1.1 200 OK\r\nContent-Type: application/x-ndjson\r\nTransfer-Encoding: chunked\r\n\r\n"


def chunk(data: bytes) -> bytes:
    return b"%x\r\n%s\r\n" % (len(data), data)


def read_request(conn: socket.socket) -> None:
    """The whole request, head and body, so the answer never meets a client still sending."""
    data = b""
    while b"\r\n\r\n" not in data:
        data += conn.recv(65536)
    head, body = data.split(b"\r\n\r\n", 1)
    length = next((int(line.split(b":")[1]) for line in head.split(b"\r\n")
                   if line.lower().startswith(b"content-length:")), 0)  # fmt: skip
    while len(body) < length:
        body += conn.recv(65536)


@pytest.fixture
def answering(tmp_path: Path) -> Iterator[tuple[Path, list[bytes]]]:
    """A Unix socket that reads one request and writes the bytes put in its list, then closes (or, with
    none, holds the connection open and says nothing until the test ends)."""
    path = tmp_path / "s"
    listener = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    listener.bind(str(path))
    listener.listen(1)
    answer: list[bytes] = []
    done = threading.Event()

    def serve() -> None:
        conn, _ = listener.accept()
        with conn:
            read_request(conn)
            if answer:
                conn.sendall(answer[0])
            else:
                done.wait(30)

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    yield path, answer
    done.set()
    listener.close()


def test_a_step_answer_that_breaks_off_mid_chunk_is_a_link_error(answering: tuple[Path, list[bytes]]) -> None:
    path, answer = answering
    answer.append(CHUNKED + b'40\r\n{"kind": "said", ')
    with pytest.raises(LinkError, match="broke off its answer: IncompleteRead"):
        Client(path, timeout_s=5.0).capsule("DRS1").sync(say=lambda _: None)


def test_a_step_answer_that_stalls_past_the_timeout_is_a_link_error(
    answering: tuple[Path, list[bytes]],
) -> None:
    path, _ = answering
    with pytest.raises(LinkError, match="broke off its answer|did not answer"):
        Client(path, timeout_s=0.5).capsule("DRS1").sync(say=lambda _: None)


def test_a_step_that_does_not_parse_is_a_link_error_naming_the_verb(
    answering: tuple[Path, list[bytes]],
) -> None:
    path, answer = answering
    answer.append(CHUNKED + chunk(b"not json\n") + b"0\r\n\r\n")
    with pytest.raises(LinkError, match="step of /capsules/DRS1/sync does not parse"):
        Client(path, timeout_s=5.0).capsule("DRS1").sync(say=lambda _: None)


def test_an_answer_of_the_wrong_shape_is_a_link_error_naming_the_verb(
    answering: tuple[Path, list[bytes]],
) -> None:
    path, answer = answering
    body = b'"a string where the hello belongs"'
    answer.append(b"HTTP/1.1 200 OK\r\nContent-Length: %d\r\n\r\n%s" % (len(body), body))
    with pytest.raises(LinkError, match="answer to GET /hello does not parse"):
        Client(path, timeout_s=5.0).hello()


def test_an_answer_that_breaks_off_after_its_last_step_keeps_the_step(
    answering: tuple[Path, list[bytes]],
) -> None:
    """The action's ``Done`` arrived whole and the answer's end did not (the server stopped): the action
    finished, so the client says so, not a bare ``IncompleteRead`` that reads as a failure."""
    path, answer = answering
    done = b'{"type":"done","lines":[],"ok":true,"arm":null,"sync":{"uploaded":["a.bin"],"skipped":0,"bytes_sent":10,"left_out":[]}}\n'
    answer.append(CHUNKED + chunk(done))
    report = Client(path, timeout_s=5.0).capsule("DRS1").sync(say=lambda _: None)
    assert report.uploaded == ("a.bin",) and report.bytes_sent == 10


def test_a_failure_step_whose_answer_breaks_off_after_it_is_still_that_failure(
    answering: tuple[Path, list[bytes]],
) -> None:
    path, answer = answering
    answer.append(CHUNKED + chunk(b'{"type":"failure","kind":"refused","error":"DRS1: no sync in flight"}\n'))
    with pytest.raises(RefusedError, match="no sync in flight"):
        Client(path, timeout_s=5.0).capsule("DRS1").sync(say=lambda _: None)
