"""``ancsh serve``: a long-running process that keeps the networks loaded and answers predict / track-step requests
(JSON over HTTP on localhost; ``docs/serve.md``)."""

from __future__ import annotations

import sys
from pathlib import Path

from ._args import non_negative_int, positive_int

__all__ = ["register"]


def register(sub) -> None:
    p = sub.add_parser("serve", help="keep the networks loaded and answer predict / track requests over HTTP "
                                     "(localhost, JSON; docs/serve.md)")
    p.add_argument("--host", default="127.0.0.1", help="address to listen on (default 127.0.0.1: this machine only)")
    p.add_argument("--port", type=non_negative_int, default=8765, help="port (default 8765; 0: a free one)")
    p.add_argument("--root", type=Path, default=None,
                   help="the folder requests may read files from (depth_path, mask_path, intrinsics_path); paths "
                        "outside it are refused. Without it requests send images as bytes only")
    p.add_argument("--categories", default="", help="comma-separated categories loaded at start: names, spec files "
                   "or built category folders (others load on their first request)")
    p.add_argument("--threads", type=positive_int, default=1, help="torch threads (default 1)")
    p.add_argument("--max-body-mb", type=positive_int, default=64, help="largest request body in MiB (default 64)")
    p.add_argument("--verbose", action="store_true", help="log every request on stderr")
    p.set_defaults(func=run)


def run(args) -> int:
    import torch

    from ..data.conventions import resolve_category
    from ..service import PredictionService, make_server

    if args.root is not None and not args.root.is_dir():
        raise ValueError(f"--root: {args.root} is not a folder")
    torch.set_num_threads(args.threads)
    try:
        categories = [resolve_category(c.strip()) for c in args.categories.split(",") if c.strip()]
        service = PredictionService(root=args.root, categories=categories)
    except Exception as exc:  # a missing category's weights: say which option
        raise ValueError(f"--categories: {exc}") from None
    server = make_server(service, args.host, args.port, max_body_bytes=args.max_body_mb << 20, verbose=args.verbose)
    print(f"ancsh serve: {server.url} (root {args.root.resolve() if args.root else 'none: images as bytes only'}; "
          f"loaded {', '.join(categories) or 'nothing yet'}); Ctrl-C stops", file=sys.stderr, flush=True)
    try:
        server.serve_forever()
    except KeyboardInterrupt:
        print("ancsh serve: stopped", file=sys.stderr)
    finally:
        server.server_close()
    return 0
