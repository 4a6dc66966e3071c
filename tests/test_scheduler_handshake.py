"""A --scheduler address answered by something that is not dask is refused in one line,
exit 3, within the connect timeout (issue 26): fake servers on loopback."""

from __future__ import annotations

import http.server
import os
import socket
import subprocess
import sys
import threading
import time

import pytest

import uqdrape.ensemble.run as run_module
from conftest import assert_one_line_error, write_study
from uqdrape.cli import main as cli
from uqdrape.ensemble.handshake import check_scheduler


class _Server:
    """A TCP server on 127.0.0.1 that does ``reply(conn)`` with each connection it accepts."""

    def __init__(self, reply):
        self.sock = socket.create_server(("127.0.0.1", 0))
        self.address = f"tcp://127.0.0.1:{self.sock.getsockname()[1]}"
        self.reply = reply
        threading.Thread(target=self._serve, daemon=True).start()

    def _serve(self):
        while True:
            try:
                conn, _ = self.sock.accept()
            except OSError:
                return
            with conn:
                self.reply(conn)

    def close(self):
        self.sock.close()


def _http_at_once(conn):
    conn.sendall(b"HTTP/1.1 200 OK\r\nContent-Length: 2\r\n\r\nok")
    time.sleep(0.5)


def _hang_up(conn):
    pass


@pytest.fixture()
def http_server():
    """A real HTTP server (it waits for a request before it says anything)."""
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), http.server.BaseHTTPRequestHandler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    yield f"tcp://127.0.0.1:{server.server_address[1]}"
    server.shutdown()
    server.server_close()


@pytest.mark.parametrize("reply, why", [(_http_at_once, "does not speak dask's protocol"),
                                        (_hang_up, "closed the connection")])
def test_a_server_that_is_not_dask_is_refused_at_once(reply, why):
    server = _Server(reply)
    start = time.monotonic()
    with pytest.raises(OSError) as err:
        check_scheduler(server.address, 10)
    assert time.monotonic() - start < 2
    server.close()
    assert err.value.filename == server.address and why in err.value.strerror


def test_a_silent_server_is_refused_at_the_timeout(http_server):
    start = time.monotonic()
    with pytest.raises(OSError) as err:
        check_scheduler(http_server, 1)
    assert 1 <= time.monotonic() - start < 3
    assert "sent no dask handshake within 1 s" in err.value.strerror


def test_a_refused_port_is_tried_until_the_timeout():
    port = socket.create_server(("127.0.0.1", 0))
    address = f"tcp://127.0.0.1:{port.getsockname()[1]}"
    port.close()  # nothing listens there now
    start = time.monotonic()
    with pytest.raises(OSError) as err:
        check_scheduler(address, 1)
    assert 0.7 <= time.monotonic() - start < 3
    assert "cannot reach the dask scheduler within 1 s (ConnectionRefusedError)" in err.value.strerror


def test_a_dask_scheduler_passes_and_still_serves():
    from distributed import Client, LocalCluster

    with LocalCluster(n_workers=1, processes=False, protocol="tcp://", host="127.0.0.1",
                      dashboard_address=None) as cluster:
        start = time.monotonic()
        check_scheduler(cluster.scheduler_address, 10)
        assert time.monotonic() - start < 1
        with Client(cluster.scheduler_address, timeout=10) as client:
            assert client.submit(sum, [1, 2]).result() == 3


def test_other_protocols_are_left_to_distributed():
    check_scheduler("tls://127.0.0.1:1", 0.1)
    check_scheduler("tcp://no-port-digits:x", 0.1)


def test_run_against_an_http_server_is_one_line_exit_3_and_writes_nothing(tmp_path, http_server, capsys,
                                                                            monkeypatch):
    monkeypatch.setattr(run_module, "SCHEDULER_TIMEOUT", 1)
    study = write_study(tmp_path)
    assert cli(["run", str(study), "--scheduler", http_server, "--no-report"]) == 3
    assert_one_line_error(capsys.readouterr().err, valid=[http_server, "is it a dask scheduler?"])
    assert not (tmp_path / "tiny").exists()  # no run.json, no chunks/, no lock: the folder was never made


def test_a_design_run_against_a_closed_port_writes_nothing(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(run_module, "SCHEDULER_TIMEOUT", 0.5)
    port = socket.create_server(("127.0.0.1", 0))
    address = f"tcp://127.0.0.1:{port.getsockname()[1]}"
    port.close()
    study = tmp_path / "design.toml"
    text = (run_module.Path(__file__).parents[1] / "studies" / "design-nosecone-symmetrise.toml").read_text()
    assert "[output]" not in text
    study.write_text(text + f'\n[output]\ndirectory = "{tmp_path / "design"}"\n')
    assert cli(["run", str(study), "--scheduler", address, "--no-report"]) == 3
    assert_one_line_error(capsys.readouterr().err, valid=[address, "ConnectionRefusedError"])
    assert not (tmp_path / "design").exists()


def test_the_command_against_an_answering_http_server_is_one_line(tmp_path):
    """As a user sees it: a fresh interpreter, exit 3, stderr the one line (no MemoryError),
    well within the 10 s connect timeout after start-up."""
    server = _Server(_http_at_once)
    study = write_study(tmp_path)
    env = {k: v for k, v in os.environ.items() if k != "PYTHONWARNINGS"}
    done = subprocess.run([sys.executable, "-m", "uqdrape.cli", "-q", "run", str(study), "--scheduler",
                           server.address, "--no-report"], capture_output=True, text=True, timeout=120, env=env)
    server.close()
    assert done.returncode == 3, done.stderr
    assert_one_line_error(done.stderr, valid=[server.address, "does not speak dask's protocol"])
