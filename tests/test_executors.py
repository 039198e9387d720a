"""Executors (ancsh.executors): local processes and Ray give the same shards and tables as one process,
and a worker that dies loses no complete shard.

The Ray tests share one local Ray (2 CPUs, no dashboard) started by a module fixture; they need the
``ray`` extra (``pip install 'ancsh[ray]'``, installed by the test set-up).
"""

import os
import sys
from pathlib import Path

import numpy as np
import pytest

from ancsh.cli import main
from ancsh.data.dataset import ShardReader, read_arrays
from ancsh.data.generate import GenerationConfig, _FrameWorker, generate_dataset
from ancsh.data.render import Intrinsics
from ancsh.executors import LocalExecutor, RayExecutor, WorkerLost, make_executor, ray_available

SMALL = Intrinsics.kinect(160, 120)


def config(**kw):
    base = dict(category="laptop", intrinsics=SMALL, num_points=64, shard_size=3, min_part_pixels=5, seed=11)
    base.update(kw)
    return GenerationConfig(**base)


def assert_same_dataset(a: Path, b: Path):
    """The same shard files, frames (every array, value for value) and stored settings."""
    names = sorted(p.name for p in a.glob("*.h5"))
    assert names == sorted(p.name for p in b.glob("*.h5")) and names
    for name in names:
        ra, rb = ShardReader(a / name), ShardReader(b / name)
        assert ra.attrs["config"] == rb.attrs["config"] and ra.frame_start == rb.frame_start
    xa, xb = read_arrays(a), read_arrays(b)
    assert set(xa) == set(xb)
    for k in xa:
        if xa[k].dtype == object:
            assert list(xa[k]) == list(xb[k]), k
        else:
            np.testing.assert_array_equal(xa[k], xb[k], err_msg=k)


class _DiesOnce:
    """A frame worker whose process dies (``os._exit``) at its first task holding frame ``kill_at``,
    once: the first time it creates ``marker``. Importable by worker processes (see the Ray fixture)."""

    def __init__(self, config, kill_at: int, marker: str):
        self.inner, self.kill_at, self.marker = _FrameWorker(config), kill_at, marker

    def __call__(self, indices):
        if self.kill_at in indices:
            try:
                fd = os.open(self.marker, os.O_CREAT | os.O_EXCL | os.O_WRONLY)
            except FileExistsError:
                pass
            else:
                os.close(fd)
                os._exit(1)  # as a kill -9 or the OOM killer would: no clean-up, no exception
        return self.inner(indices)


def _dies_once(kill_at: int, marker: Path):
    """A worker factory for ``generate_dataset`` (``factory(config)``) with a :class:`_DiesOnce` worker."""
    import functools

    return functools.partial(_make_dies_once, kill_at=kill_at, marker=str(marker))


def _make_dies_once(config, *, kill_at, marker):
    return _DiesOnce(config, kill_at, marker)


# --- without Ray -------------------------------------------------------------------------
def test_executor_options_are_checked(monkeypatch, capsys):
    with pytest.raises(ValueError, match="executor: expected one of"):
        make_executor("dask")
    with pytest.raises(ValueError, match="workers: expected an int >= 1"):
        LocalExecutor(0)
    with pytest.raises(ValueError, match="ray_address: only with the ray executor"):
        make_executor("local", address="auto")
    with pytest.raises(ValueError, match="workers: give the worker count to the executor"):
        generate_dataset(config(), 3, "unused", workers=2, executor=LocalExecutor(2))
    monkeypatch.setitem(sys.modules, "ray", None)  # as if Ray were not installed
    assert main(["data", "generate", "--category", "laptop", "--frames", "1", "--executor", "ray", "--out", "x"]) == 2
    assert "--executor ray: Ray is not installed; install it with: pip install 'ancsh[ray]'" in capsys.readouterr().err
    with pytest.raises(ImportError, match="pip install 'ancsh\\[ray\\]'"):
        list(RayExecutor(1).imap(_FrameWorker, (config(),), [[0]]))


@pytest.mark.slow
def test_a_dead_local_worker_raises_and_keeps_complete_shards(reference, tmp_path, monkeypatch):
    """A local worker process killed mid-run: WorkerLost (not a hang), complete shards kept, a rerun resumes."""
    monkeypatch.setattr("ancsh.data.generate._frame_worker", _dies_once(10, tmp_path / "killed"))
    out = tmp_path / "run"
    with pytest.raises(WorkerLost, match="a local worker process died"):
        generate_dataset(config(), 12, out, executor=LocalExecutor(2), progress=False)
    assert (tmp_path / "killed").exists()
    kept = sorted(p.name for p in out.glob("*.h5"))
    assert "laptop_train_00003.h5" not in kept  # the dead worker's shard
    report = generate_dataset(config(), 12, out, progress=False)  # the marker exists: no second death
    assert set(report.skipped) == {int(n[-8:-3]) for n in kept} and 3 in report.written
    assert_same_dataset(reference, out)


# --- with Ray ----------------------------------------------------------------------------
@pytest.fixture(scope="module")
def reference(tmp_path_factory) -> Path:
    """The 12 frames of ``config()`` (4 shards) generated in this process: what every executor must write."""
    out = tmp_path_factory.mktemp("reference")
    generate_dataset(config(), 12, out, progress=False)
    return out


@pytest.fixture(scope="module")
def ray_session():
    """One local Ray for the module (2 CPUs, no dashboard); its workers can import this test module."""
    ray = pytest.importorskip("ray")
    old = os.environ.get("PYTHONPATH")
    os.environ["PYTHONPATH"] = os.pathsep.join([str(Path(__file__).parent), *([old] if old else [])])
    try:
        ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
        yield ray
    finally:
        ray.shutdown()
        if old is None:
            os.environ.pop("PYTHONPATH", None)
        else:
            os.environ["PYTHONPATH"] = old


@pytest.mark.slow
def test_a_killed_ray_worker_is_restarted_and_its_shard_redone(ray_session, reference, tmp_path, monkeypatch):
    monkeypatch.setattr("ancsh.data.generate._frame_worker", _dies_once(7, tmp_path / "killed"))
    report = generate_dataset(config(), 12, tmp_path / "ray", executor=RayExecutor(2, max_retries=2), progress=False)
    assert (tmp_path / "killed").exists()  # a worker did die (at frame 7, in shard 2)
    assert report.written == (0, 1, 2, 3) and report.frames_generated == 12
    assert_same_dataset(reference, tmp_path / "ray")


@pytest.mark.slow
def test_a_killed_ray_worker_without_retries_loses_no_complete_shard(ray_session, reference, tmp_path, monkeypatch):
    """Four one-task shards on two workers (0, 2 on the first; 1, 3 on the second): the second dies in
    shard 3. Shard 0 is always kept (the first worker never dies); shard 1 is too unless the dying
    process took its result with it. Every kept shard is complete and verified; the rerun makes the rest."""
    monkeypatch.setattr("ancsh.data.generate._frame_worker", _dies_once(10, tmp_path / "killed"))
    out = tmp_path / "ray"
    with pytest.raises(WorkerLost, match="a Ray worker died"):
        generate_dataset(config(), 12, out, executor=RayExecutor(2, max_retries=0), progress=False)
    kept = sorted(int(p.name[-8:-3]) for p in out.glob("*.h5"))
    assert kept[0] == 0 and 3 not in kept and kept == list(range(len(kept)))  # results are taken in task order
    for s in kept:
        ShardReader(out / f"laptop_train_{s:05d}.h5").arrays()  # every checksum verified
    assert not list(out.glob("*.tmp*"))
    report = generate_dataset(config(), 12, out, executor=RayExecutor(2), progress=False)
    assert report.skipped == tuple(kept) and report.written == tuple(range(len(kept), 4)) and report.replaced == ()
    assert_same_dataset(reference, out)


@pytest.mark.slow
def test_cli_generate_on_ray_writes_the_shards_of_one_process(ray_session, reference, tmp_path, capsys):
    args = ["data", "generate", "--category", "laptop", "--frames", "12", "--shard-size", "3", "--points", "64",
            "--width", "160", "--height", "120", "--min-part-pixels", "5", "--seed", "11", "--quiet"]
    assert main([*args, "--workers", "2", "--executor", "ray", "--out", str(tmp_path / "ray")]) == 0
    assert "4 shards, 12 frames generated" in capsys.readouterr().out
    assert_same_dataset(reference, tmp_path / "ray")
    assert main([*args, "--ray-address", "auto", "--out", str(tmp_path / "x")]) == 2
    assert "--ray-address: only with --executor ray" in capsys.readouterr().err


def _without_times(value):
    """``value`` with every measured time (the keys of TIMING_KEYS, FrameRecord.time_s) left out."""
    from ancsh.studies.table1 import TIMING_KEYS

    if isinstance(value, dict):
        return {k: _without_times(v) for k, v in value.items() if k not in (*TIMING_KEYS, "time_s")}
    if isinstance(value, list):
        return [_without_times(v) for v in value]
    return value


@pytest.mark.slow
def test_ray_evaluation_gives_the_same_tables_as_one_process(ray_session):
    pytest.importorskip("torch")
    from ancsh.studies.table1 import evaluate_category, json_safe, summarize

    kw = dict(frames=3, methods=("per_part", "exact_reduced"), progress=False)
    one = evaluate_category("laptop", **kw)
    ray_run = evaluate_category("laptop", executor=RayExecutor(2), **kw)
    assert ray_run["settings"]["executor"] == "2 Ray worker(s) on a local Ray"
    assert [r["frame"] for r in ray_run["records"]] == [0, 1, 2]
    a, b = json_safe(_without_times(one["records"])), json_safe(_without_times(ray_run["records"]))
    assert a == b  # every error of every part, joint and method, value for value
    assert json_safe(_without_times(summarize(one))) == json_safe(_without_times(summarize(ray_run)))


def _assert_close(a, b, where="records"):
    """Equal structure and non-float values; floats equal to 1e-9 (relative)."""
    if isinstance(a, float) and isinstance(b, float):
        assert a == pytest.approx(b, rel=1e-9, abs=1e-12, nan_ok=True), where
    elif isinstance(a, (list, dict)):
        assert type(a) is type(b) and len(a) == len(b), where
        for k in (a if isinstance(a, dict) else range(len(a))):
            _assert_close(a[k], b[k], f"{where}[{k!r}]")
    else:
        assert a == b, where


@pytest.mark.slow
def test_ray_cad_evaluation_gives_the_same_records_as_one_process(ray_session):
    """Value for value up to the last bits: open3d's ICP itself differs in the last bits between two plain
    runs in two processes (measured: 1e-15 relative), so floats are compared to 1e-9; every AD verdict,
    status and the tables built from them are equal."""
    from dataclasses import asdict

    from ancsh.studies.cad import EvalConfig, run_evaluation

    cfg = EvalConfig(frames=1, points=300, procedural=(("laptop", 0), ("drawer", 0)), shared=False, image_size=(160, 120))
    methods = ("per_part_icp", "whole_object_icp")
    one, meta = run_evaluation(cfg, methods=methods)
    ray_run, ray_meta = run_evaluation(cfg, methods=methods, executor=RayExecutor(2))
    assert [r.object for r in ray_run] == [r.object for r in one] and len(one) == 2 * 2 * len(methods)
    _assert_close(_without_times([asdict(r) for r in one]), _without_times([asdict(r) for r in ray_run]))
    assert meta["objects"] == ray_meta["objects"]


def test_a_ray_address_where_nothing_listens_is_refused_quickly(tmp_path, capsys):
    import socket
    import time

    from ancsh.executors import probe_ray_address

    with socket.socket() as s:  # a port that was free a moment ago: nothing listens there
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    t0 = time.monotonic()
    with pytest.raises(ConnectionError, match=f"no Ray cluster answers at 127.0.0.1:{port}"):
        probe_ray_address(f"127.0.0.1:{port}")
    with pytest.raises(ConnectionError, match=f"ray://127.0.0.1:{port}"):
        probe_ray_address(f"ray://127.0.0.1:{port}", timeout_s=1.0)
    assert time.monotonic() - t0 < 12.0
    for bad in ("nohost", "host:", ":6379", "ray://x:port"):
        with pytest.raises(ValueError, match="address: expected"):
            probe_ray_address(bad)
    probe_ray_address("auto")  # left to Ray, which fails at once without a cluster
    with socket.socket() as server:  # something listening is accepted
        server.bind(("127.0.0.1", 0))
        server.listen()
        probe_ray_address(f"127.0.0.1:{server.getsockname()[1]}")
    if ray_available():
        code = main(["evaluate", "--category", "laptop", "--frames", "1", "--executor", "ray", "--ray-address",
                     f"127.0.0.1:{port}", "--out", str(tmp_path / "o"), "--no-progress"])
        err = capsys.readouterr().err
        assert code == 2 and "--ray-address: no Ray cluster answers" in err and "Traceback" not in err


class _SlowPidWorker:
    """A worker that writes its PID to a folder and sleeps (a long task)."""

    def __init__(self, folder):
        self.folder = folder

    def __call__(self, task):
        import time

        Path(self.folder, f"{os.getpid()}.pid").write_text(str(task))
        time.sleep(60)
        return task


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    try:  # a zombie (exited, not yet reaped by its new parent) counts as gone
        return Path(f"/proc/{pid}/stat").read_text().split(")")[-1].split()[0] != "Z"
    except OSError:
        return True


@pytest.mark.skipif(sys.platform != "linux", reason="reads /proc")
def test_local_workers_exit_when_their_parent_is_killed(tmp_path):
    import signal
    import subprocess
    import time

    script = (f"import sys; sys.path.insert(0, {str(Path(__file__).parent)!r})\n"
              "from test_executors import _SlowPidWorker\n"
              "from ancsh.executors import LocalExecutor\n"
              f"list(LocalExecutor(2).imap(_SlowPidWorker, ({str(tmp_path)!r},), range(4)))\n")
    parent = subprocess.Popen([sys.executable, "-c", script])
    try:
        deadline = time.monotonic() + 60
        while len(list(tmp_path.glob("*.pid"))) < 2 and time.monotonic() < deadline:
            time.sleep(0.2)
        pids = [int(p.stem) for p in tmp_path.glob("*.pid")]
        assert len(pids) == 2 and all(_alive(p) for p in pids)
        parent.send_signal(signal.SIGKILL)  # no chance to shut the pool down
        parent.wait()
        deadline = time.monotonic() + 10
        while any(_alive(p) for p in pids) and time.monotonic() < deadline:
            time.sleep(0.2)
        assert not any(_alive(p) for p in pids)
    finally:
        parent.kill()
        for p in tmp_path.glob("*.pid"):
            try:
                os.kill(int(p.stem), signal.SIGKILL)
            except ProcessLookupError:
                pass
