"""``uqdrape serve`` under hostile and concurrent clients on 127.0.0.1: stalled
connections, bodies of a negative or huge length, non-object JSON and malformed request
lines hold only their own connection; every good request of 50 concurrent clients is
answered, every bad one gets the protocol's JSON error without the request echoed, and
nothing reaches stderr. The server runs in a thread of the test process; every socket has
a timeout, so no loop here waits without bound."""

from __future__ import annotations

import http.client
import json
import socket
import threading
import time
from concurrent.futures import ThreadPoolExecutor

import pytest
from conftest import write_study

from uqdrape.cli import main
from uqdrape.workflow import load_study, nominal_input, serve_study

SECTIONS = {"uncertainty": {"orientation": {"dist": "normal", "mean": 0.0, "sd": 2.0}}}
WAIT_S = 120.0  # the most any one answer may take on a loaded 2-core machine


class Served:
    """A study served in a thread; ``port`` once it listens; ``stop()`` ends it."""

    def __init__(self, study, **options):
        self.lines, self.port, self.served = [], None, None
        self._up = threading.Event()
        self._thread = threading.Thread(target=self._serve, args=(study,), kwargs=options, daemon=True)
        self._thread.start()
        deadline = time.monotonic() + WAIT_S
        while not self._up.wait(0.2):
            assert self._thread.is_alive() and time.monotonic() < deadline, "the server did not start"

    def _serve(self, study, **options):
        def announce(line):
            self.lines.append(line)
            if self.port is None:
                self.port = int(line.rsplit(":", 1)[1])
                self._up.set()
        self.served = serve_study(study, port=0, announce=announce, **options)

    def join(self):
        self._thread.join(WAIT_S)
        assert not self._thread.is_alive(), "the server did not stop by itself"


def request(port, method, path, body=None, headers=None):
    """(status, parsed JSON) of one request on its own connection."""
    conn = http.client.HTTPConnection("127.0.0.1", port, timeout=WAIT_S)
    try:
        conn.request(method, path, body=body, headers=headers or {})
        reply = conn.getresponse()
        return reply.status, json.loads(reply.read())
    finally:
        conn.close()


def raw(port, data: bytes) -> tuple[int, dict]:
    """(status, parsed JSON) of a request sent as raw bytes, the reply read to its end."""
    with socket.create_connection(("127.0.0.1", port), timeout=WAIT_S) as s:
        s.sendall(data)
        reply = b""
        while chunk := s.recv(65536):
            reply += chunk
    head, _, body = reply.partition(b"\r\n\r\n")
    return int(head.split()[1]), json.loads(body)


def stalled(port, data: bytes) -> socket.socket:
    """A connection that sends ``data`` and then nothing."""
    s = socket.create_connection(("127.0.0.1", port), timeout=WAIT_S)
    s.sendall(data)
    return s


def still_open(s: socket.socket) -> bool:
    """Whether the server has neither closed nor answered this connection."""
    s.setblocking(False)
    try:
        s.recv(1, socket.MSG_PEEK)  # an answer or the server's close
        return False
    except BlockingIOError:
        return True
    finally:
        s.settimeout(WAIT_S)


def post(name="forward", **fields):
    return json.dumps({"name": name, **fields})


NUMBERS = "[" + ",".join(["123456.789"] * 1000) + "]"
#: Bad requests: (what is sent, the status expected). None of their bodies may come back.
MALFORMED = [
    (b"POST /Evaluate HTTP/1.1\r\nContent-Length: 3\r\n\r\n[1]", 400),  # a JSON array, not an object
    (b"POST /Evaluate HTTP/1.1\r\nContent-Length: 4\r\n\r\nnull", 400),
    (b"POST /InputSizes HTTP/1.1\r\nContent-Length: 7\r\n\r\n{nojson", 400),
    (b"POST /Evaluate HTTP/1.1\r\nContent-Length: -1\r\n\r\n", 413),
    (b"POST /Evaluate HTTP/1.1\r\nContent-Length: 99999999999999\r\n\r\n", 413),
    (b"POST /Evaluate HTTP/1.1\r\nContent-Length: x\r\n\r\n", 411),
    (b"POST /Evaluate HTTP/1.1\r\n\r\n", 411),
    (b"GARBAGE\r\n\r\n", 400),
    (b"PUT /Evaluate HTTP/1.1\r\n\r\n", 501),
    (b"GET /secret-path-xyz HTTP/1.1\r\n\r\n", 404),
    (f"POST /Evaluate HTTP/1.1\r\nContent-Length: {len(post(input=[['zz-text', 1.0]]))}\r\n\r\n"
     f"{post(input=[['zz-text', 1.0]])}".encode(), 400),
    (f"POST /Evaluate HTTP/1.1\r\nContent-Length: {len(post(input=[json.loads(NUMBERS)]))}\r\n\r\n"
     f"{post(input=[json.loads(NUMBERS)])}".encode(), 400),
    (f"POST /Evaluate HTTP/1.1\r\nContent-Length: {len(post(name='zz-model'))}\r\n\r\n{post(name='zz-model')}"
     .encode(), 400),
]


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    return load_study(write_study(tmp_path_factory.mktemp("serve"), **SECTIONS))


def test_50_clients_are_answered_while_stalled_connections_hang_and_bad_requests_get_json(study, capfd):
    x0 = nominal_input(study)
    server = Served(study, max_requests=12, timeout_s=600.0, connection_timeout_s=600.0)  # stalls outlast the test
    port = server.port
    expected = request(port, "POST", "/Evaluate", post(input=[x0], config={}))
    assert expected[0] == 200 and len(expected[1]["output"][0]) == len(study.sensitivity.qoi)
    stalls = [stalled(port, b""), stalled(port, b"POST /Evaluate HTTP/1.1\r\nContent-Le"),
              stalled(port, b"POST /Evaluate HTTP/1.1\r\nContent-Length: 100\r\n\r\n{\"na")]

    def client(k):
        """Client k: two good requests (every fifth an evaluation) and one malformed one."""
        answers = [request(port, "GET", "/Info"), request(port, "POST", "/InputSizes", post())]
        if k % 5 == 0:
            answers.append(request(port, "POST", "/Evaluate", post(input=[x0], config={})))
        sent, status = MALFORMED[k % len(MALFORMED)]
        return answers, (raw(port, sent), status, sent)

    start = time.monotonic()
    with ThreadPoolExecutor(50) as pool:
        results = list(pool.map(client, range(50)))
    elapsed = time.monotonic() - start
    assert elapsed < WAIT_S
    for answers, ((got, reply), status, sent) in results:
        assert answers[0] == (200, {"protocolVersion": 1.0, "models": ["forward"]})
        assert answers[1] == (200, {"inputSizes": [len(x0)]})
        for evaluation in answers[2:]:
            assert evaluation == expected  # the same drape, concurrent or not
        assert got == status and set(reply) == {"error"} and set(reply["error"]) == {"type", "message"}
        message = json.dumps(reply)
        assert len(message) < 300 and "zz-" not in message and "123456" not in message and "secret" not in message
    assert all(still_open(s) for s in stalls)  # they hold their own threads, no one else's
    assert request(port, "POST", "/Evaluate", post(input=[x0])) == expected  # the 12th and last
    server.join()
    for s in stalls:
        s.close()
    assert server.served == 12
    err = capfd.readouterr().err
    assert "Traceback" not in err and err == ""


def test_an_idle_connection_is_dropped_after_the_connection_timeout_and_max_requests_stops(study, capfd):
    server = Served(study, max_requests=1, timeout_s=300.0, connection_timeout_s=1.0)
    idle = stalled(server.port, b"POST /Evaluate HTTP/1.1\r\n")
    start = time.monotonic()
    assert idle.recv(1) == b""  # closed by the server, without an answer
    assert time.monotonic() - start < 30.0
    idle.close()
    status, reply = request(server.port, "POST", "/Evaluate", post(input=[nominal_input(study)]))
    assert status == 200 and len(reply["output"]) == len(study.force_levels)
    server.join()
    assert server.served == 1
    assert capfd.readouterr().err == ""


@pytest.mark.parametrize("flags, named", [(["--port", "99999"], "--port"), (["--port", "-1"], "--port"),
                                          (["--timeout", "inf"], "--timeout"), (["--timeout", "nan"], "--timeout")])
def test_an_impossible_port_or_timeout_is_one_line(tmp_path, capsys, flags, named):
    path = write_study(tmp_path, **SECTIONS)
    assert main(["serve", str(path), *flags]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith("uqdrape serve: error: " + named)
