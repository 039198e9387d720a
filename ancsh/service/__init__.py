"""``ancsh serve``: the categories' networks loaded once behind JSON over HTTP on localhost.

- :mod:`.requests`: requests checked before any work (fields, images as paths inside the served folder or bytes);
- :mod:`.service`: :class:`PredictionService`, the work (predict and track-step, the same JSON as ``ancsh predict``
  and ``ancsh track``), one request at a time;
- :mod:`.http`: the standard library's threading HTTP server in front of it (:func:`make_server`);
- :mod:`.client`: :class:`ServiceClient`, a small client (standard library only).

``docs/serve.md`` documents the endpoints and fields.
"""

from __future__ import annotations

from .client import ServiceClient, ServiceError
from .http import make_server
from .requests import RequestError
from .service import PredictionService

__all__ = ["PredictionService", "RequestError", "ServiceClient", "ServiceError", "make_server"]
