"""Helpers and fixtures shared by every test folder."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

_OPEN_AT_FILE_ZERO = 0.6  # the synthetic oven's door is open by this angle at the file's state 0


def _write_oven_urdf(folder: Path, *, door_fixed=False, knob=True, drawer=False, base_geometry=True,
                     door_limits="limited", hatch=False) -> Path:
    """A 0.6 m cube (z up) with a bottom-hinged door on its +x face, open by
    ``_OPEN_AT_FILE_ZERO`` at the file's state 0 (closed at ``-_OPEN_AT_FILE_ZERO``). ``door_limits``:
    ``"limited"`` (to 1.2 rad), ``"continuous"`` (a continuous joint) or ``"huge"`` (+-1e9 rad)."""
    folder.mkdir(parents=True, exist_ok=True)
    base_visual = ('<visual><origin xyz="0 0 0.3"/><geometry><box size="0.6 0.6 0.6"/></geometry></visual>'
                   if base_geometry else "")
    door_type = "fixed" if door_fixed else "continuous" if door_limits == "continuous" else "revolute"
    limit = {"limited": f'<limit lower="{-_OPEN_AT_FILE_ZERO}" upper="1.2"/>', "continuous": "",
             "huge": '<limit lower="-1e9" upper="1e9"/>'}[door_limits]
    parts = [
        f'<link name="body">{base_visual}</link>',
        '<link name="door"><visual><origin xyz="0.01 0 0.29"/><geometry><box size="0.02 0.56 0.58"/></geometry></visual></link>',
        f'<joint name="door_joint" type="{door_type}"><parent link="body"/><child link="door"/>'
        f'<origin xyz="0.3 0 0" rpy="0 {_OPEN_AT_FILE_ZERO} 0"/><axis xyz="0 1 0"/>{limit}</joint>',
    ]
    semantics = ["body heavy oven_body", "door hinge door"]
    if knob:
        parts += [
            '<link name="knob"><visual><geometry><cylinder radius="0.02" length="0.02"/></geometry></visual></link>',
            '<joint name="knob_joint" type="continuous"><parent link="body"/><child link="knob"/>'
            '<origin xyz="0.31 0.2 0.55"/><axis xyz="1 0 0"/></joint>',
        ]
        semantics.append("knob hinge knob")
    if hatch:
        parts += [
            '<link name="hatch"><visual><origin xyz="-0.15 0 0.01"/><geometry><box size="0.3 0.3 0.02"/></geometry>'
            '</visual></link>',
            '<joint name="hatch_joint" type="revolute"><parent link="body"/><child link="hatch"/>'
            '<origin xyz="0.1 0 0.6"/><axis xyz="0 -1 0"/><limit lower="0" upper="1.5"/></joint>',
        ]
        semantics.append("hatch hinge door")
    if drawer:
        parts += [
            '<link name="tray"><visual><origin xyz="-0.2 0 0"/><geometry><box size="0.4 0.5 0.05"/></geometry></visual></link>',
            '<joint name="tray_joint" type="prismatic"><parent link="body"/><child link="tray"/>'
            '<origin xyz="0.29 0 0.1"/><axis xyz="1 0 0"/><limit lower="0" upper="0.3"/></joint>',
        ]
        semantics.append("tray slider drawer")
    (folder / "model.urdf").write_text('<?xml version="1.0"?><robot name="t">' + "".join(parts) + "</robot>")
    (folder / "semantics.txt").write_text("\n".join(semantics) + "\n")
    return folder / "model.urdf"


@pytest.fixture
def make_oven_urdf():
    """``make_oven_urdf(folder, **options) -> Path``: a synthetic URDF oven with known ground truth
    (its door is closed at file state ``-make_oven_urdf.open_at_file_zero``; see :func:`_write_oven_urdf`)."""
    _write_oven_urdf.open_at_file_zero = _OPEN_AT_FILE_ZERO
    return _write_oven_urdf


def central_differences(f, x, h: float = 1e-6) -> np.ndarray:
    """Central-difference derivative of ``f`` at ``x`` (float64).

    ``f`` maps an ``(n,)`` vector to an array of shape ``S`` (a scalar: ``S = ()``); the result
    has shape ``S + (n,)`` (the Jacobian ``(m, n)`` of a vector function, the gradient ``(n,)``
    of a scalar one).
    """
    x = np.asarray(x, dtype=np.float64)
    cols = []
    for e in np.eye(x.size):
        cols.append((np.asarray(f(x + h * e), dtype=np.float64) - np.asarray(f(x - h * e), dtype=np.float64)) / (2 * h))
    return np.stack(cols, axis=-1)


@pytest.fixture
def numeric_derivative():
    """:func:`central_differences` (the one finite-difference helper of the tests)."""
    return central_differences


@pytest.fixture
def make_refiner(tmp_path):
    """``make_refiner(category="laptop", perturb=15.0)``: the shipped first-stage weights of ``category`` relabelled as
    a refinement network (``refine_perturb_deg``; untrained for it), written into the test's folder; its path."""
    def make(category: str = "laptop", perturb: float = 15.0) -> Path:
        import torch

        from ancsh.learned.network.weights import read_torch_file, weights_path

        data = read_torch_file(weights_path(category), argument="weights")
        data["config"] = {**data["config"], "refine_perturb_deg": perturb}
        path = tmp_path / f"{category}_refine.pt"
        torch.save(data, path)
        return path

    return make


_OVEN_LIKE_SPEC = """spec_version = 1
name = "{name}"
rest = "door closed (0)"
diagonal_m = [0.5, 1.5]
{extra}
[[parts]]
name = "base"

[[parts]]
name = "door"
{part}
[[joints]]
name = "door_hinge"
type = "revolute"
child = "door"
zero = "closed"
positive = "opens"
side = "front"
rest_deg = 0
range_deg = [0, 180]
"""


@pytest.fixture
def make_category_spec():
    """``make_category_spec(folder, name="toaster", extra="", part='semantics = ["door"]', file=None) -> Path``: a
    category spec file of an oven-like category (a base and a front door on a revolute hinge, 0..180 deg) written
    into ``folder`` (``file``: its name, default ``<name>.toml``); ``extra``: top-level lines, ``part``: the door's."""
    def write(folder: Path, name="toaster", extra="", part='semantics = ["door"]', file=None) -> Path:
        path = Path(folder) / (file or f"{name}.toml")
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(_OVEN_LIKE_SPEC.format(name=name, extra=extra, part=part))
        return path

    return write


@pytest.fixture
def clean_registry(monkeypatch):
    """The process's known categories and search path as they were before the test (what it registers is forgotten)."""
    from ancsh.data import category_spec
    from ancsh.data.conventions import CONVENTIONS

    monkeypatch.setattr(CONVENTIONS, "_searched", (None, {}))
    monkeypatch.setenv(category_spec.SEARCH_PATH_VARIABLE, "")  # restored (unset) after the test
