"""Argument types and option groups shared by the commands (argparse only; the library never imports this)."""

from __future__ import annotations

from ..executors import EXECUTORS, RAY_MISSING, make_executor, ray_available


#: What each category name read from a spec file or folder on this command line was given as (the path), for the
#: command lines reports record (:func:`category_as_given`).
_GIVEN: dict = {}


def category(text: str) -> str:
    """A ``--category`` value: a category's name as it is (checked where it is used); a category spec file or a
    built category folder is read, registered (:func:`ancsh.data.conventions.register_category`) and its name
    returned (the path remembered for :func:`category_as_given`); a wrong spec is argparse's error naming the file and
    the key."""
    import argparse

    from ..data.conventions import is_category_path, resolve_category

    if not is_category_path(text):
        return text
    try:
        name = resolve_category(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    _GIVEN[name] = text
    return name


def category_as_given(name: str) -> str:
    """A ``--category`` value as the user gave it (the path, for a spec file or folder read by :func:`category`), for
    the command lines that reports record."""
    return _GIVEN.get(name, name)


def named_value(item: str, option: str, form: str) -> tuple[str, str]:
    """``NAME=VALUE`` of a repeatable option split in two; an item without ``=`` or with an empty side is refused
    naming ``option`` and the expected ``form`` (e.g. ``"CATEGORY=FILE"``)."""
    name, sep, value = item.partition("=")
    if not sep or not name or not value:
        raise ValueError(f"{option}: expected {form}, got {item!r}")
    return name, value


def fit_config_fields(text: str, option: str) -> dict:
    """The JSON object of ``FitConfig`` fields given as ``option`` (e.g. ``'{"npcs_bias_weight": 0.01}'``); text that
    is not JSON, or JSON that is not an object, is refused naming ``option`` (the fields themselves are checked where
    the ``FitConfig`` is built)."""
    import json

    try:
        fields = json.loads(text)
    except ValueError as exc:
        raise ValueError(f"{option}: not JSON ({exc})") from None
    if not isinstance(fields, dict):
        raise ValueError(f"{option}: expected a JSON object of FitConfig fields, got {text!r}")
    return fields


def _number(text: str, convert, accept, expected: str):
    """``convert(text)`` when ``accept`` takes it, else argparse's error "expected <expected>, got ..."."""
    import argparse

    try:
        value = convert(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected {expected}, got {text!r}") from None
    if not accept(value):
        raise argparse.ArgumentTypeError(f"expected {expected}, got {value}")
    return value


def changed_options(args, defaults: dict) -> list[str]:
    """The command-line tokens of the options of ``args`` that differ from ``defaults`` (``{dest: default}``, in
    order): ``--dest-name value`` (every item of a list value), or the bare ``--dest-name`` of a switch (a
    ``store_true`` option: default ``False``, value ``True``), so that a report's command line re-runs it. An
    option missing from ``args`` counts as its default."""
    tokens = []
    for dest, default in defaults.items():
        value = getattr(args, dest, default)
        if value == default:
            continue
        flag = f"--{dest.replace('_', '-')}"
        if value is True and default is False:
            tokens.append(flag)
            continue
        values = value if isinstance(value, (list, tuple)) else [value]
        tokens += [flag, *(str(v) for v in values)]
    return tokens


def shipped_categories_option(categories) -> list[str]:
    """``--categories``: the categories given (default: every one with shipped weights); a category without shipped
    weights is refused, naming the shipped ones."""
    from ..learned.network.weights import shipped_categories

    shipped = shipped_categories()
    chosen = list(categories) if categories else list(shipped)
    unknown = [c for c in chosen if c not in shipped]
    if unknown:
        raise ValueError(f"--categories: no shipped weights for {unknown}; shipped: {shipped}")
    return chosen


def positive_int(text: str) -> int:
    return _number(text, int, lambda v: v > 0, "a positive integer")


def non_negative_int(text: str) -> int:
    return _number(text, int, lambda v: v >= 0, "a non-negative integer")


def positive_float(text: str) -> float:
    import math

    return _number(text, float, lambda v: math.isfinite(v) and v > 0, "a positive number")


def check_picture_path(path, option: str) -> None:
    """Refuse a picture path whose suffix matplotlib cannot write, before any work is done (no suffix: ``.png``)."""
    from pathlib import Path

    from matplotlib.backend_bases import FigureCanvasBase

    suffix = Path(path).suffix.lower().lstrip(".")
    formats = FigureCanvasBase.get_supported_filetypes()
    if suffix and suffix not in formats:
        raise ValueError(f"{option}: cannot write a .{suffix} picture ({path}); use one of "
                         f"{', '.join('.' + f for f in sorted(formats))}")


def add_executor_arguments(parser, *, workers_default: int, workers_help: str) -> None:
    """Add ``--workers``, ``--executor`` and ``--ray-address`` to a command's parser."""
    parser.add_argument("--workers", type=positive_int, default=workers_default, help=workers_help)
    parser.add_argument("--executor", choices=EXECUTORS, default="local",
                        help="where the workers run: local processes (default) or a Ray cluster "
                             "(pip install 'ancsh[ray]')")
    parser.add_argument("--ray-address", default=None, metavar="ADDR",
                        help="with --executor ray: a running cluster ('auto', 'ray://head:10001'); "
                             "default: a local Ray started for this command")


def executor_from_args(args):
    """The executor of parsed :func:`add_executor_arguments` options (errors name the option)."""
    if args.ray_address is not None and args.executor != "ray":
        raise ValueError("--ray-address: only with --executor ray")
    if args.executor == "ray" and not ray_available():
        raise ValueError(f"--executor ray: {RAY_MISSING}")
    if args.ray_address is not None:  # before any work: Ray itself would retry a dead address for minutes
        from ..executors import probe_ray_address

        try:
            probe_ray_address(args.ray_address)
        except (ValueError, ConnectionError) as exc:
            raise type(exc)(f"--ray-address: {str(exc).removeprefix('address: ')}") from None
    return make_executor(args.executor, args.workers, address=args.ray_address)

