"""``ancsh serve``: the same results as ``predict`` / ``track`` (as JSON, as paths, as raw bytes, from parallel
clients), a clear 4xx for every malformed request without a dead server, and no file read outside its folder."""

from __future__ import annotations

import http.client
import json
import os
import socket
import threading
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest
from PIL import Image

from ancsh.data.generate import FrameGenerator, GenerationConfig
from ancsh.learned.inference.predict import predict_depth, read_depth
from ancsh.outputs import without_timings
from ancsh.service import PredictionService, ServiceClient, ServiceError, make_server
from ancsh.service.requests import PathPolicy, RequestError, parse_predict


def _without_times(x):
    """``x`` without its timings and its ``input`` block (the same inputs, sent by different routes)."""
    return without_timings(x, drop=("input",))


@pytest.fixture(scope="module")
def frames():
    """Noise-free depth images of held-out laptops (test split) and their intrinsics."""
    gen = FrameGenerator(GenerationConfig(category="laptop", split="test", seed=0))
    out = []
    for index in (2, 3):
        frame = gen.frame(index)
        _, renderer = gen.instance(frame.instance_index)
        out.append(renderer.render(frame.joint_states_abs, frame.T_cam_base, frame.intrinsics).depth)
    return out, frame.intrinsics


@pytest.fixture(scope="module")
def root(tmp_path_factory, frames):
    """The served folder: the first depth as a 16-bit PNG and as .npy, the intrinsics as K.json."""
    depths, intr = frames
    folder = tmp_path_factory.mktemp("served")
    Image.fromarray(np.round(depths[0] * 1000).astype(np.uint16)).save(folder / "depth.png")
    np.save(folder / "depth.npy", depths[0])
    (folder / "K.json").write_text(json.dumps(intr.to_json()))
    return folder


@pytest.fixture(scope="module")
def server(root):
    service = PredictionService(root=root)
    srv = make_server(service, "127.0.0.1", 0)
    thread = threading.Thread(target=srv.serve_forever, daemon=True)
    thread.start()
    yield srv
    srv.shutdown()
    srv.server_close()


def _raw(server, method: str, path: str, body: bytes | None = None, headers=None) -> tuple[int, dict]:
    host, port = server.server_address[:2]
    conn = http.client.HTTPConnection(host, port, timeout=60)
    try:
        conn.request(method, path, body=body, headers=headers or {})
        response = conn.getresponse()
        return response.status, json.loads(response.read())
    finally:
        conn.close()


def test_a_prediction_is_what_predict_gives_as_array_path_and_raw_png(server, frames, root):
    depths, intr = frames
    client = ServiceClient(server.url)
    options = {"hypotheses": 1}
    direct = _without_times(predict_depth(read_depth(root / "depth.png"), intr, "laptop", **options).to_json())
    by_path = client.predict("depth.png", "K.json", "laptop", **options)
    assert by_path["schema"] == "ancsh.prediction/2" and by_path["input"]["depth"] == "depth.png"
    assert _without_times(by_path) == direct
    status, raw = _raw(server, "POST", "/predict?category=laptop&intrinsics=K.json&hypotheses=1",
                       (root / "depth.png").read_bytes(), {"Content-Type": "image/png"})
    assert status == 200 and _without_times(raw) == direct
    as_array = client.predict(np.load(root / "depth.npy"), intr, "laptop", **options)  # metres, sent as a raw .npy
    expected = _without_times(predict_depth(depths[0], intr, "laptop", **options).to_json())
    assert _without_times(as_array) == expected and as_array["input"]["depth"] == "<npy bytes>"
    assert as_array["input"]["intrinsics"] == intr.to_json()  # from the query's fx, fy, cx, cy, width, height
    as_json = client._call("POST", "/predict", client.request_body(np.load(root / "depth.npy"), intr, "laptop", **options))
    assert _without_times(as_json) == expected  # the same as base64 in a JSON body


def test_parallel_clients_get_each_their_own_answer(server, frames):
    depths, intr = frames
    requests = [(depths[i % 2], seed) for i, seed in enumerate((0, 1, 2, 3))]
    client = ServiceClient(server.url)
    with ThreadPoolExecutor(4) as pool:
        answers = list(pool.map(lambda r: client.predict(r[0], intr, "laptop", seed=r[1], hypotheses=1), requests))
    for (depth, seed), answer in zip(requests, answers):
        assert answer["input"]["seed"] == seed
        assert _without_times(answer) == _without_times(predict_depth(depth, intr, "laptop", seed=seed,
                                                                      hypotheses=1).to_json())


def test_a_track_session_gives_the_records_of_track(server, frames):
    from ancsh.learned.inference.provider import LearnedProvider
    from ancsh.service.service import TRACK_NETWORK_EVERY
    from ancsh.tracking.stream import track_depth
    from ancsh.tracking.tracker import CategoryTracker, TrackerConfig

    depths, intr = frames
    client = ServiceClient(server.url)
    sequence = [depths[0], depths[0], depths[1]]
    served = [client.track("s1", d, intr, "laptop", reset=i == 0) for i, d in enumerate(sequence)]
    tracker = CategoryTracker(LearnedProvider("laptop", seed=0), TrackerConfig(network_every=TRACK_NETWORK_EVERY),
                              category="laptop", rng=0)
    direct = [track_depth(d, intr, tracker, i, category="laptop") for i, d in enumerate(sequence)]
    assert [r["frame"] for r in served] == [0, 1, 2] and {r["session"] for r in served} == {"s1"}
    assert [_without_times({k: v for k, v in r.items() if k not in ("schema", "session")}) for r in served] == \
        [_without_times(r) for r in direct]
    with pytest.raises(ServiceError, match="409.*tracks 'laptop'"):
        client.track("s1", depths[0], intr, "oven")
    assert client.end_track("s1") == {"session": "s1", "ended": True}


MALFORMED = [
    ("POST", "/predict", b"not json", {"Content-Type": "application/json"}, 400, "not JSON"),
    ("POST", "/predict", b"[1, 2]", {}, 400, "a JSON object"),
    ("POST", "/predict", b"{}", {}, 400, "category"),
    ("POST", "/predict", json.dumps({"category": "laptop"}).encode(), {}, 400, "intrinsics"),
    ("POST", "/predict", json.dumps({"category": "laptop", "intrinsics_path": "K.json"}).encode(), {}, 400, "depth"),
    ("POST", "/predict", json.dumps({"category": "laptop", "intrinsics_path": "K.json", "depth_path": "../x.png"}).encode(),
     {}, 403, "outside"),
    ("POST", "/predict", json.dumps({"category": "laptop", "intrinsics_path": "K.json", "depth_path": "/etc/hostname"}).encode(),
     {}, 403, "outside"),
    ("POST", "/predict", json.dumps({"category": "laptop", "intrinsics_path": "K.json", "depth_path": "none.png"}).encode(),
     {}, 404, "no such file"),
    ("POST", "/predict", json.dumps({"category": "laptop", "intrinsics_path": "K.json", "depth_png_base64": "@@"}).encode(),
     {}, 400, "base64"),
    ("POST", "/predict", json.dumps({"category": "laptop", "intrinsics_path": "K.json", "depth_png_base64": "aGVsbG8="}).encode(),
     {}, 400, "depth_png_base64"),
    ("POST", "/predict", json.dumps({"category": "laptop", "intrinsics": {"fx": 1}, "depth_path": "depth.png"}).encode(),
     {}, 400, "intrinsics"),
    ("POST", "/predict", json.dumps({"category": "laptop", "intrinsics_path": "K.json", "depth_path": "depth.png",
                                     "seed": -1}).encode(), {}, 400, "seed"),
    ("POST", "/predict", json.dumps({"category": "laptop", "intrinsics_path": "K.json", "depth_path": "depth.png",
                                     "seed": True}).encode(), {}, 400, "seed"),
    ("POST", "/predict", json.dumps({"category": "laptop", "intrinsics_path": "K.json", "depth_path": "depth.png",
                                     "pixel": [1, "a"]}).encode(), {}, 400, "pixel"),
    ("POST", "/predict", json.dumps({"category": "laptop", "intrinsics_path": "K.json", "depth_path": "depth.png",
                                     "pixel": [1, 2], "box": [0, 0, 5, 5]}).encode(), {}, 400, "at most one"),
    ("POST", "/predict", json.dumps({"category": "laptop", "intrinsics_path": "K.json", "depth_path": "depth.png",
                                     "colour": 1}).encode(), {}, 400, "unknown field"),
    ("POST", "/predict", json.dumps({"category": "no_such_category", "intrinsics_path": "K.json",
                                     "depth_path": "depth.png"}).encode(), {}, 404, "category"),
    ("POST", "/predict?category=laptop", b"\x89PNG broken", {"Content-Type": "image/png"}, 400, "intrinsics"),
    ("POST", "/predict?category=laptop&intrinsics=K.json&seed=x", b"\x00", {"Content-Type": "image/png"}, 400, "seed"),
    ("POST", "/predict?category=laptop&fx=500&fy=500", b"\x00", {"Content-Type": "application/x-npy"}, 400,
     "but not cx, cy, width, height"),
    ("POST", "/predict", json.dumps({"category": "laptop", "intrinsics_path": "K.json", "depth_npy_bytes": "AAAA"}).encode(),
     {}, 400, "raw request body only"),
    ("POST", "/predict", b"{}", {"Content-Type": "text/plain"}, 415, "Content-Type"),
    ("POST", "/predict", b"{}", {"Content-Length": "999999999999"}, 413, "at most"),
    ("GET", "/predict", None, {}, 405, "not allowed"),
    ("DELETE", "/health", None, {}, 405, "not allowed"),
    ("GET", "/nothing", None, {}, 404, "no such endpoint"),
    ("POST", "/track", json.dumps({"session": "a b", "category": "laptop"}).encode(), {}, 400, "session"),
    ("POST", "/track/end", b"{}", {}, 400, "session"),
]


@pytest.mark.parametrize("case", MALFORMED, ids=[f"{c[0]} {c[1]} {c[-1]}" for c in MALFORMED])
def test_a_malformed_request_gets_a_4xx_naming_the_problem(server, case):
    method, path, body, headers, status, reason = case
    got, answer = _raw(server, method, path, body, headers)
    assert got == status and reason in answer["error"] and answer["status"] == status


def test_the_server_survives_a_thousand_malformed_requests(server):
    before = ServiceClient(server.url).health()["requests"]["refused"]
    statuses = [_raw(server, *MALFORMED[i % len(MALFORMED)][:4])[0] for i in range(1000)]
    assert all(400 <= s < 500 for s in statuses)
    host, port = server.server_address[:2]
    for garbage in (b"GARBAGE\r\n\r\n", b"\x00\xff" * 100, b"GET / HTTP/1.1\r\nContent-Length: x\r\n\r\n"):
        with socket.create_connection((host, port), timeout=10) as s:
            s.sendall(garbage)
            s.shutdown(socket.SHUT_WR)
            s.recv(1 << 16)
    health = ServiceClient(server.url).health()
    assert health["status"] == "ok" and health["requests"]["refused"] >= before + 1000


def test_paths_are_read_inside_the_root_only(root, tmp_path):
    outside = tmp_path / "secret.png"
    outside.write_bytes((root / "depth.png").read_bytes())
    link = root / "link.png"
    if not link.exists():
        os.symlink(outside, link)
    policy = PathPolicy(root)
    assert policy.resolve("depth.png", "depth_path") == (root / "depth.png").resolve()
    assert policy.resolve(str(root / "depth.png"), "depth_path") == (root / "depth.png").resolve()
    for bad in ("../secret.png", str(outside), "link.png", "sub/../../secret.png"):
        with pytest.raises(RequestError, match="outside") as err:
            policy.resolve(bad, "depth_path")
        assert err.value.status == 403
    with pytest.raises(RequestError, match="reads no paths") as err:
        PathPolicy(None).resolve("depth.png", "depth_path")
    assert err.value.status == 403


def test_a_request_is_checked_before_any_work(root, frames):
    _, intr = frames
    policy = PathPolicy(root)
    ok = parse_predict({"category": "laptop", "intrinsics_path": "K.json", "depth_path": "depth.png", "box": [0, 0, 9, 9]},
                       policy)
    assert ok.box == (0.0, 0.0, 9.0, 9.0) and ok.depth.shape == (intr.height, intr.width)
    small = dict(intr.to_json(), width=intr.width // 2)
    with pytest.raises(RequestError, match="depth") as err:  # the image does not have the intrinsics' size
        parse_predict({"category": "laptop", "intrinsics": small, "depth_path": "depth.png"}, policy)
    assert err.value.status == 400
    with pytest.raises(RequestError, match="max_objects"):
        parse_predict({"category": "laptop", "intrinsics_path": "K.json", "depth_path": "depth.png", "pixel": [3, 4],
                       "max_objects": 2}, policy)
