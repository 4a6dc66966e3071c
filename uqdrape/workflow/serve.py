"""A study as a UM-Bridge model (``uqdrape serve STUDY``): any UQ toolkit with a UM-Bridge
client (OpenTURNS, UQLab, MUQ, QMCPy, PyMC, emcee, ...) can evaluate the drape.

The model, named ``forward``, takes one input vector: the study's scalar uncertain
factors at their physical values, in the study's order and units (N, -, deg, mm, as
the study file gives them), then each random field's truncated Karhunen-Loeve mode
variables (standard normals, ``kl_retained`` of its variance; 0 is the field's mean),
named as ``uqdrape.ensemble.sample_columns``. Physical values rather than the SALib
standard variables, so that a caller samples the factors with its own distributions
(the study's are printed at start); the fields have no physical coordinates of their
own, so their standard variables are the input. The nominal input is every factor's
median and every mode 0.

It returns one output vector per blank-holder force level of the study: the chosen
per-drape quantities of interest (``uqdrape.stats.qoi``; default the study's
``[sensitivity] qoi``), each drape one call of the ensemble engine's ``drape_inputs``,
so an evaluation equals ``uqdrape drape`` with the same settings.

The server speaks the UM-Bridge protocol 1.0 (GET /Info; POST /ModelInfo, /InputSizes,
/OutputSizes, /Evaluate; errors as ``{"error": {"type", "message"}}``) with the standard
library's HTTP server, so serving needs no package beyond uqdrape's own; a client needs
``umbridge`` (``pip install uqdrape[serve]``) or any other UM-Bridge client. It listens
on 127.0.0.1 unless given another host, answers each connection in its own thread (one
evaluation at a time; a client idle past the connection timeout is dropped, a body larger
than the input vector needs is refused) and stops by itself after ``max_requests``
evaluations or ``timeout_s`` seconds if given. From Python::

    import umbridge
    model = umbridge.HTTPModel("http://127.0.0.1:4242", "forward")
    print(model([[0.2, 15.0]]))          # e.g. friction, orientation
"""

from __future__ import annotations

import contextlib
import json
import math
import threading
import time
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

import numpy as np

from ..ensemble import drape_inputs, inputs_from_rows, sample_columns
from ..errors import ParameterError
from ..schema import SOLVER_INPUTS
from ..stats.qoi import check_qois, realization_qois

#: Name of the served model.
MODEL_NAME = "forward"


def input_names(study) -> list[str]:
    """Names of the model's input vector: the factors, then ``field[k]`` KL modes."""
    return sample_columns(study)


def nominal_input(study) -> list[float]:
    """The nominal input vector: each factor's median, each KL mode 0."""
    d = len(study.uncertainty.factors)
    medians = [float(f.ppf(0.5)) for f in study.uncertainty.factors.values()]
    return medians + [0.0] * (len(input_names(study)) - d)


def evaluate(study, x, qoi, *, surface=None, material=None) -> list[list[float]]:
    """The QoIs ``qoi`` (one list per force level) of one drape at input vector ``x``."""
    names = input_names(study)
    try:
        x = np.asarray(x, dtype=float)
    except (TypeError, ValueError, OverflowError):  # strings, nested lists, integers past float
        x = None
    if x is None or x.shape != (len(names),) or not np.isfinite(x).all():
        raise ValueError(f"the input must be {len(names)} finite numbers ({', '.join(names)})")
    factors = study.uncertainty.factors
    d = len(factors)
    X = np.concatenate([np.full(d, 0.5), x[d:]])[None]  # factor columns replaced by their values below
    inputs = inputs_from_rows(study, X)
    for k, name in enumerate(factors):
        inp = SOLVER_INPUTS[name]
        if not inp.admits(x[k]):  # the physical limits of every entry point, not the study's distribution
            raise ValueError(f"input {name} = {x[k]:g} is invalid: {name} {inp.describe_range()}")
        inputs[name] = x[k:k + 1]
    out = []
    for force in study.force_levels:
        ds = drape_inputs(study, [0], inputs, force=force if study.is_sweep else None, surface=surface,
                          material=material)
        q = realization_qois(ds, qoi)
        out.append([float(q[name].values.ravel()[0]) for name in qoi])
    return out


class _Handler(BaseHTTPRequestHandler):
    """The UM-Bridge protocol 1.0 for one model (``server.model``: input and output sizes,
    evaluate); every error, a malformed request line included, answers as the protocol's
    ``{"error": {"type", "message"}}`` and never repeats the request back."""

    def setup(self):
        self.timeout = self.server.connection_timeout_s  # every read and write of this connection, s
        super().setup()

    def log_message(self, format, *args):  # the server's own lines go through ``announce``
        pass

    def _send(self, status: int, body: dict) -> None:
        data = json.dumps(body).encode()
        self.send_response(status)
        self.send_header("Content-Type", "application/json")
        self.send_header("Content-Length", str(len(data)))
        if status >= 400:
            self.send_header("Connection", "close")
            self.close_connection = True
        self.end_headers()
        self.wfile.write(data)

    def _error(self, status: int, kind: str, message: str) -> None:
        self._send(status, {"error": {"type": kind, "message": message}})

    def send_error(self, code, message=None, explain=None):
        """http.server's own refusals (a malformed request line or header, an unknown
        method) in the protocol's JSON, with the status's phrase rather than the request,
        under a status line even where the request line was too broken to name HTTP/1.x."""
        self.request_version = "HTTP/1.0" if self.request_version == "HTTP/0.9" else self.request_version
        self._error(int(code), "InvalidRequest", self.responses.get(code, ("bad request",))[0])

    def do_GET(self):
        if self.path == "/Info":
            self._send(200, {"protocolVersion": 1.0, "models": [MODEL_NAME]})
        else:
            self._error(404, "NotFound", "UM-Bridge asks GET /Info; no other GET is served")

    def _request(self):
        """The request's JSON object, or None once an error has been answered."""
        try:
            size = int(self.headers.get("Content-Length", ""))
        except ValueError:
            return self._error(411, "InvalidInput", "a POST needs a Content-Length of its JSON body, in bytes")
        limit = self.server.max_body_bytes
        if not 0 <= size <= limit:
            return self._error(413, "InvalidInput", f"the body's Content-Length must be 0 to {limit} bytes")
        try:
            request = json.loads(self.rfile.read(size) or b"{}")
        except (ValueError, RecursionError):  # RecursionError: JSON nested thousands deep
            return self._error(400, "InvalidInput", "the request body is not JSON")
        if not isinstance(request, dict):
            return self._error(400, "InvalidInput", "the request body must be a JSON object")
        return request

    def do_POST(self):
        model = self.server.model
        request = self._request()
        if request is None:
            return
        if request.get("name") != MODEL_NAME:
            return self._error(400, "ModelNotFound", f"the model named is not served; served: {MODEL_NAME}")
        if self.path == "/ModelInfo":
            return self._send(200, {"support": {"Evaluate": True, "Gradient": False, "ApplyJacobian": False,
                                                "ApplyHessian": False}})
        if self.path == "/InputSizes":
            return self._send(200, {"inputSizes": model.input_sizes})
        if self.path == "/OutputSizes":
            return self._send(200, {"outputSizes": model.output_sizes})
        if self.path != "/Evaluate":
            return self._error(400, "UnsupportedFeature", "only /ModelInfo, /InputSizes, /OutputSizes and "
                                                          "/Evaluate are served")
        parameters = request.get("input")
        if not (isinstance(parameters, list) and len(parameters) == 1 and isinstance(parameters[0], list)):
            return self._error(400, "InvalidInput", f"input must be one vector of {model.input_sizes[0]} numbers")
        with self.server.evaluating:  # one drape at a time; other requests are answered meanwhile
            if self.server.stopping.is_set():
                return self._error(503, "Unavailable", "the server is stopping")
            try:
                output = model(parameters[0])
            except ValueError as err:
                return self._error(400, "InvalidInput", str(err))
            except Exception as err:  # noqa: BLE001 -- a drape that fails is this request's answer, not the server's end
                return self._error(500, "EvaluationFailed", f"the drape failed ({type(err).__name__})")
            self._send(200, {"output": output})
            self.server.served += 1
            if self.server.max_requests is not None and self.server.served >= self.server.max_requests:
                self.server.stopping.set()


class _Server(ThreadingHTTPServer):
    """One thread a connection, so that a slow or idle client holds only its own."""

    daemon_threads = True
    block_on_close = False  # closing does not wait for a stalled client
    request_queue_size = 128  # connections waiting to be accepted (socketserver's 5 resets a burst of clients)

    def handle_error(self, request, client_address):
        """A connection the client broke (reset, timed out) ends quietly: no traceback."""


class _Forward:
    """The study's forward model: input and output sizes and one evaluation."""

    def __init__(self, study, qoi):
        self.study, self.qoi = study, qoi
        self.surface, self.material = study.geometry.build_mould(), study.fabric.card()
        self.input_sizes = [len(input_names(study))]
        self.output_sizes = [len(qoi)] * len(study.force_levels)

    def __call__(self, x):
        return evaluate(self.study, x, self.qoi, surface=self.surface, material=self.material)


def serve_study(study, *, host: str = "127.0.0.1", port: int = 4242, qoi=None, max_requests: int | None = None,
                timeout_s: float | None = None, connection_timeout_s: float = 30.0, announce=print) -> int:
    """Serve ``study`` as the UM-Bridge model ``forward`` at ``host``:``port`` until
    stopped (Ctrl-C, SIGTERM) or after ``max_requests`` evaluations / ``timeout_s``
    seconds; returns the evaluations served. A connection idle for ``connection_timeout_s``
    seconds in a read or write is dropped. ``announce`` gets the lines describing the
    model."""
    study.single_ply("a served model")
    qoi = check_qois(qoi if qoi else study.sensitivity.qoi)
    if max_requests is not None and max_requests < 1:
        raise ParameterError("max_requests", f"max_requests must be at least 1, got {max_requests}")
    if timeout_s is not None and not 0 < timeout_s < math.inf:
        raise ParameterError("timeout_s", f"timeout_s must be a positive finite number of seconds, got {timeout_s}")
    if not 0 <= port <= 65535:
        raise ParameterError("port", f"port must be a TCP port, 0 to 65535 (0: any free one), got {port}")
    model = _Forward(study, qoi)
    server = _Server((host, port), _Handler)
    server.model, server.served, server.max_requests = model, 0, max_requests
    server.connection_timeout_s, server.max_body_bytes = connection_timeout_s, _max_body_bytes(model)
    server.evaluating, server.stopping = threading.Lock(), threading.Event()
    factors = {name: f.describe() for name, f in study.uncertainty.factors.items()}
    announce(f"UM-Bridge model {MODEL_NAME!r} of study {study.name!r} at http://{host}:{server.server_port}")
    announce("input: " + ", ".join(f"{n} ~ {factors[n]}" if n in factors else n for n in input_names(study)))
    announce(f"nominal input: {nominal_input(study)}")
    announce(f"output per force level {list(study.force_levels)} N: {', '.join(qoi)}")
    deadline = math.inf if timeout_s is None else time.monotonic() + timeout_s
    loop = threading.Thread(target=server.serve_forever, kwargs={"poll_interval": 0.1}, daemon=True)
    with server:
        loop.start()
        with contextlib.suppress(KeyboardInterrupt):  # Ctrl-C or SIGTERM: a served model's normal end
            while not server.stopping.is_set() and time.monotonic() < deadline:
                server.stopping.wait(min(0.5, max(deadline - time.monotonic(), 0.0)))
        server.stopping.set()
        server.shutdown()
    return server.served


def _max_body_bytes(model) -> int:
    """The largest request body served, bytes: room for the input vector's numbers at their
    longest JSON spelling (25 characters) and the protocol's keys and config."""
    return 65536 + 32 * model.input_sizes[0]
