"""The command line: help, version and the demo run in-process."""

import pytest

from ancsh import __version__
from ancsh.cli import build_parser, main


def test_version(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0
    assert __version__ in capsys.readouterr().out


def test_help_lists_every_registered_command(capsys):
    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    main([])
    out = capsys.readouterr().out
    for name in sub.choices:
        assert name in out


def test_import_is_light():
    import subprocess
    import sys

    code = "import sys, ancsh; print(any(m.startswith(('torch', 'open3d', 'casadi')) for m in sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "False"


def test_changed_options_give_back_the_command_line_of_the_non_default_options():
    import argparse

    from ancsh.cli._args import changed_options

    args = argparse.Namespace(categories=["laptop", "oven"], frames=20, seed=3, box_extents="max", refiner=None)
    defaults = {"categories": None, "frames": 20, "seed": 0, "box_extents": "max", "refiner": None}
    assert changed_options(args, defaults) == ["--categories", "laptop", "oven", "--seed", "3"]
    assert changed_options(argparse.Namespace(real_frames=7), {"real_frames": 50}) == ["--real-frames", "7"]
    # a switch (store_true) is its bare flag; an option missing from the namespace counts as its default
    assert changed_options(argparse.Namespace(quick=True, json=False), {"quick": False, "json": False, "seed": 0}) == ["--quick"]
