"""``ancsh serve``'s HTTP side: JSON over HTTP on the standard library's threading server, in front of a
:class:`~ancsh.service.service.PredictionService`.

Endpoints: ``GET /health``, ``GET /version``, ``POST /predict`` (a JSON object, or a raw depth image with the
options as query parameters), ``POST /track`` and ``POST /track/end``. A request the service refuses gets a 4xx
with ``{"error": reason, "status": code}``; an unexpected failure inside a prediction a 500 with its message --
the server itself keeps serving either way. Bodies need a ``Content-Length`` and at most ``max_body_bytes``.
"""

from __future__ import annotations

import json
import threading
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from urllib.parse import parse_qs, urlsplit

from ..outputs import json_safe
from .requests import RequestError

__all__ = ["MAX_BODY_BYTES", "ServiceServer", "make_server"]

#: Largest request body (bytes): a 4K 16-bit depth PNG in base64 with room to spare.
MAX_BODY_BYTES = 64 * 1024 * 1024
#: Seconds a connection may stay silent before the server drops it (a client that never sends its body).
SOCKET_TIMEOUT_S = 30.0

_RAW_TYPES = {"image/png": "depth_png_bytes", "application/x-npy": "depth_npy_bytes",
              "application/octet-stream": "depth_npy_bytes"}
_QUERY_NUMBERS = {"seed": int, "max_objects": int, "hypotheses": int, "points": int, "max_depth": float,
                  "depth_scale": float}
#: The intrinsics as query parameters (instead of ``intrinsics=`` a path): all of them or none.
_QUERY_INTRINSICS = {"fx": float, "fy": float, "cx": float, "cy": float, "width": int, "height": int}


def _query_body(query: str, raw: bytes, content_type: str) -> dict:
    """The request body of a raw-image request: the image's bytes under its kind (as they came: no base64 round
    trip), the query's options typed, ``fx, fy, cx, cy, width, height`` gathered into ``intrinsics``."""
    body = {_RAW_TYPES[content_type]: raw}
    intrinsics = {}
    for key, values in parse_qs(query, keep_blank_values=True, strict_parsing=False).items():
        if len(values) != 1:
            raise RequestError(400, f"{key}: given {len(values)} times in the query")
        value = values[0]
        try:
            if key in _QUERY_INTRINSICS:
                intrinsics[key] = _QUERY_INTRINSICS[key](value)
                continue
            if key in _QUERY_NUMBERS:
                value = _QUERY_NUMBERS[key](value)
            elif key in ("pixel", "box"):
                value = [float(v) for v in value.split(",")]
            elif key == "isolate":
                if value not in ("true", "false"):
                    raise ValueError(value)
                value = value == "true"
        except ValueError:
            raise RequestError(400, f"{key}: cannot read {values[0]!r} from the query") from None
        if key == "intrinsics":
            key = "intrinsics_path"
        body[key] = value
    if intrinsics:
        missing = [k for k in _QUERY_INTRINSICS if k not in intrinsics]
        if missing:
            raise RequestError(400, f"intrinsics: the query gives {', '.join(intrinsics)} but not {', '.join(missing)} "
                                    "(all of fx, fy, cx, cy, width, height, or intrinsics= a path)")
        body["intrinsics"] = intrinsics
    return body


class _Handler(BaseHTTPRequestHandler):
    server_version = "ancsh-serve"
    protocol_version = "HTTP/1.1"
    timeout = SOCKET_TIMEOUT_S

    # -- plumbing ------------------------------------------------------------------------------------------------
    def log_message(self, format, *args):  # noqa: A002 - the standard library's signature
        if self.server.verbose:
            super().log_message(format, *args)

    def _send(self, status: int, data: dict) -> None:
        payload = (json.dumps(json_safe(data), allow_nan=False) + "\n").encode()
        self.send_response(status)
        self.send_header("Content-Type", "application/json")
        self.send_header("Content-Length", str(len(payload)))
        self.end_headers()
        self.wfile.write(payload)

    def _error(self, status: int, message: str) -> None:
        with self.server.count_lock:
            self.server.service.counts["refused" if status < 500 else "failed"] += 1
        self._send(status, {"error": message, "status": status})

    def _body(self):
        length = self.headers.get("Content-Length")
        if length is None:
            raise RequestError(411, "Content-Length: required")
        try:
            n = int(length)
        except ValueError:
            raise RequestError(400, f"Content-Length: not a number ({length!r})") from None
        if n < 0:
            raise RequestError(400, f"Content-Length: negative ({n})")
        if n > self.server.max_body_bytes:
            self.close_connection = True  # the body is not read: the connection cannot be reused
            raise RequestError(413, f"request body: {n} bytes, at most {self.server.max_body_bytes}")
        raw = self.rfile.read(n)
        if len(raw) != n:
            raise RequestError(400, f"request body: {len(raw)} of {n} bytes arrived")
        content_type = (self.headers.get("Content-Type") or "application/json").split(";")[0].strip().lower()
        query = urlsplit(self.path).query
        if content_type in _RAW_TYPES:
            return _query_body(query, raw, content_type)
        if content_type not in ("application/json", "application/x-www-form-urlencoded"):  # (curl -d sends the latter)
            raise RequestError(415, f"Content-Type: expected application/json, image/png or application/x-npy, got "
                                    f"{content_type!r}")
        if query:
            raise RequestError(400, "query: options of a JSON request go in its body")
        try:
            return json.loads(raw.decode("utf-8"))
        except (UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise RequestError(400, f"request body: not JSON ({exc})") from None

    def _route(self, method: str) -> None:
        path = urlsplit(self.path).path.rstrip("/") or "/"
        routes = {("GET", "/health"): lambda: self.server.service.health(),
                  ("GET", "/version"): lambda: self.server.service.version(),
                  ("POST", "/predict"): lambda: self.server.service.predict(self._body()),
                  ("POST", "/track"): lambda: self.server.service.track(self._body()),
                  ("POST", "/track/end"): lambda: self.server.service.end_track(self._body())}
        try:
            if (method, path) not in routes:
                if any(p == path for _, p in routes):
                    allowed = ", ".join(m for m, p in routes if p == path)
                    raise RequestError(405, f"{method} {path}: not allowed (use {allowed})")
                raise RequestError(404, f"{path}: no such endpoint (GET /health, GET /version, POST /predict, "
                                        "POST /track, POST /track/end)")
            self._send(200, routes[(method, path)]())
        except RequestError as exc:
            self._error(exc.status, str(exc))
        except (ConnectionError, TimeoutError):
            self.close_connection = True
        except Exception as exc:  # noqa: BLE001 - a failure inside one prediction never stops the server
            self._error(500, f"{type(exc).__name__}: {exc}")

    def do_GET(self):  # noqa: N802 - the standard library's names
        self._route("GET")

    def do_POST(self):  # noqa: N802
        self._route("POST")

    def do_PUT(self):  # noqa: N802
        self._route("PUT")

    def do_DELETE(self):  # noqa: N802
        self._route("DELETE")


class ServiceServer(ThreadingHTTPServer):
    """The threading HTTP server of one :class:`~ancsh.service.service.PredictionService`."""

    daemon_threads = True
    allow_reuse_address = True

    def __init__(self, address, service, *, max_body_bytes: int = MAX_BODY_BYTES, verbose: bool = False):
        super().__init__(address, _Handler)
        self.service, self.max_body_bytes, self.verbose = service, int(max_body_bytes), verbose
        self.count_lock = threading.Lock()

    @property
    def url(self) -> str:
        host, port = self.server_address[:2]
        return f"http://{host}:{port}"


def make_server(service, host: str = "127.0.0.1", port: int = 8765, **kwargs) -> ServiceServer:
    """A :class:`ServiceServer` bound to ``host:port`` (port 0: a free one, see :attr:`ServiceServer.url`)."""
    return ServiceServer((host, int(port)), service, **kwargs)
