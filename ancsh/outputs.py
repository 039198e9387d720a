"""Where commands write their results, and what every JSON result carries.

- Report-writing commands (``ancsh evaluate``, ``ancsh evaluate-cad``, ``ancsh bench fit``) write into
  a fresh folder ``ancsh_results/<command>-<UTC time>/`` unless ``--out`` is given; the committed
  ``docs/results/`` is rewritten only with ``--update-docs`` (or an explicit ``--out`` there).
- Every JSON result carries :func:`provenance`: the ancsh version and, where a network was used,
  the SHA-256 of its weights file (the schema is documented in ``docs/json_schema.md``).
- Files are written atomically (:func:`write_bytes_atomically`: a temporary file and a rename in the
  target folder, so a failed write leaves the old file or none, never half of one).

numpy-free and light: imported by the command-line modules at parse time.
"""

from __future__ import annotations

import datetime
import os
import tempfile
from pathlib import Path

__all__ = ["RESULTS_ROOT", "DOCS_RESULTS", "fresh_output_dir", "report_path", "file_sha256", "json_safe", "provenance", "without_timings",
           "write_bytes_atomically"]

#: Parent of the fresh output folders (relative to the working directory).
RESULTS_ROOT = Path("ancsh_results")
#: The committed results, rewritten only on request.
DOCS_RESULTS = Path("docs/results")


def fresh_output_dir(command: str, root=None) -> Path:
    """Create and return a new folder ``<root>/<command>-<YYYYmmdd-HHMMSS>[-n]`` (never an existing one).

    Parameters
    ----------
    command : str
        Names the folder, e.g. ``"evaluate-laptop"``.
    root : str or Path, optional
        Parent folder (default :data:`RESULTS_ROOT`).
    """
    root = RESULTS_ROOT if root is None else Path(root)
    stamp = datetime.datetime.now(datetime.timezone.utc).strftime("%Y%m%d-%H%M%S")
    root.mkdir(parents=True, exist_ok=True)
    for n in range(1, 1000):
        path = root / (f"{command}-{stamp}" if n == 1 else f"{command}-{stamp}-{n}")
        try:
            path.mkdir()
        except FileExistsError:
            continue
        return path
    raise FileExistsError(f"{root}: no free folder name for {command}-{stamp}")


def report_path(out, *, update_docs: bool, docs_name: str, command: str) -> Path:
    """The file a report-writing command writes.

    ``out`` (the ``--out`` option) wins; else ``--update-docs`` selects ``docs/results/<docs_name>``;
    else a file of that name in a :func:`fresh_output_dir`.
    """
    if out is not None:
        return Path(out)
    if update_docs:
        return DOCS_RESULTS / docs_name
    return fresh_output_dir(command) / docs_name


def output_flags(out, *, update_docs: bool) -> list[str]:
    """The words of a reproducing command line that say where the report went (the inputs of
    :func:`report_path`): ``["--out", out]``, ``["--update-docs"]`` or none."""
    if out is not None:
        return ["--out", str(out)]
    return ["--update-docs"] if update_docs else []


def file_sha256(path) -> str:
    """SHA-256 hex digest of a file's bytes."""
    import hashlib

    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def provenance(weights=None, weights_sha256: str | None = None) -> dict:
    """``{"ancsh_version", "weights", "weights_sha256"}`` for a JSON result (weights entries ``None`` without a file).

    ``weights_sha256`` is used when given (a digest taken when the file was loaded), else computed.
    """
    from ._version import __version__

    if weights_sha256 is None and weights is not None and Path(weights).is_file():
        weights_sha256 = file_sha256(weights)
    return {"ancsh_version": __version__, "weights": None if weights is None else str(weights),
            "weights_sha256": weights_sha256}


def json_safe(x):
    """A JSON-safe copy: NaN / inf -> ``None``, numpy scalars -> Python, tuples -> lists."""
    import numpy as np

    if isinstance(x, dict):
        return {k: json_safe(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [json_safe(v) for v in x]
    if isinstance(x, (np.floating, float)):
        return float(x) if np.isfinite(x) else None
    if isinstance(x, np.integer):
        return int(x)
    return x


def without_timings(x, drop=()):
    """A copy of a result's JSON without what two runs of the same computation may differ in: its timings
    (``timings_ms``, ``time_ms``) and the durations its notes quote (``"42 ms"`` becomes ``"<time> ms"``); ``drop``
    names more keys to leave out (e.g. ``"input"``, where the same inputs came by different routes)."""
    import re

    if isinstance(x, dict):
        return {k: without_timings(v, drop) for k, v in x.items() if k not in ("timings_ms", "time_ms", *drop)}
    if isinstance(x, list):
        return [without_timings(v, drop) for v in x]
    if isinstance(x, str):
        return re.sub(r"\d+(\.\d+)? ms", "<time> ms", x)
    return x


def write_bytes_atomically(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file and a rename: a failed write leaves
    the old file (or none), never half a file. Creates the parent folders. An ``OSError`` names ``path``, not the
    temporary file."""
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    except OSError as exc:
        raise OSError(exc.errno, exc.strerror, str(path)) from exc
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
    except OSError as exc:
        Path(tmp).unlink(missing_ok=True)
        raise OSError(exc.errno, exc.strerror, str(path)) from exc
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
