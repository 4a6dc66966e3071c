"""Is a ``tcp://`` address a dask.distributed scheduler? Asked before distributed connects.

distributed trusts the first 8 bytes a server sends as the size of its handshake message:
from an HTTP server that answers at once, ``HTTP/1.1`` reads as about 3.5e18 bytes and
distributed tries to allocate them (MemoryError); an HTTP server that waits for a request
leaves it waiting past its own timeout. A dask scheduler writes its handshake as soon as
it accepts a connection (``distributed.comm.core.Listener.on_connection``): an 8-byte
size (native uint64, 58 bytes with distributed 2026.8) and the message. So the check
connects, reads those 8 bytes within the timeout and closes; nothing is sent, so a real
scheduler only sees a client that left before its handshake.
"""

from __future__ import annotations

import errno
import socket
import struct
import time

#: distributed's default scheduler port, for an address without one.
DEFAULT_PORT = 8786
#: Largest handshake size accepted (bytes); a scheduler's is under a hundred.
MAX_HANDSHAKE_BYTES = 1 << 20
#: Wait between connection attempts while a scheduler may still be starting (s).
RETRY_S = 0.2


def check_scheduler(address: str, timeout: float) -> None:
    """Raise OSError (EHOSTUNREACH, one line, ``filename`` the address) unless ``address``
    connects within ``timeout`` s and its first 8 bytes are a dask handshake size. A
    refused connection is tried again until the timeout, as distributed does. Addresses
    of other protocols (tls://, ucx://, ...) and ones that do not parse as host:port are
    left to distributed."""
    scheme, _, rest = address.partition("://")
    host, colon, port = rest.rpartition(":")
    if not colon:
        host, port = rest, str(DEFAULT_PORT)
    if scheme != "tcp" or not host or not port.isdigit():
        return
    host = host.strip("[]")  # an IPv6 literal
    deadline = time.monotonic() + timeout

    def fail(why):
        raise OSError(errno.EHOSTUNREACH, why, address)

    while True:
        try:
            sock = socket.create_connection((host, int(port)), timeout=max(deadline - time.monotonic(), 0.01))
            break
        except ConnectionRefusedError as err:
            if time.monotonic() + RETRY_S >= deadline:
                fail(f"cannot reach the dask scheduler within {timeout:g} s ({type(err).__name__})")
            time.sleep(RETRY_S)
        except OSError as err:  # a timeout, no route, an unknown host
            fail(f"cannot reach the dask scheduler within {timeout:g} s ({type(err).__name__})")
    head = b""
    with sock:
        try:
            while len(head) < 8:
                sock.settimeout(max(deadline - time.monotonic(), 0.01))
                data = sock.recv(8 - len(head))
                if not data:
                    break
                head += data
        except TimeoutError:
            fail(f"the server there sent no dask handshake within {timeout:g} s: is it a dask scheduler?")
        except OSError as err:
            fail(f"the server there closed the connection ({type(err).__name__}): is it a dask scheduler?")
    if len(head) < 8:
        fail("the server there closed the connection before a dask handshake: is it a dask scheduler?")
    (size,) = struct.unpack("Q", head)
    if not 0 < size <= MAX_HANDSHAKE_BYTES:
        fail("the server there does not speak dask's protocol (its first bytes are not a dask handshake): "
             "is it a dask scheduler's address?")
