"""The Python module against independent numbers: PyTorch's values of the models saved by
tests/make_model_fixtures.py, the command line's own output files on the same inputs (byte for
byte), analytic renders; and its behaviour as a Python library (errors, arrays, GIL, leaks).

Run by CTest (tests/CMakeLists.txt) with PYTHONPATH holding the built module and
FILLGS_MODEL_FIXTURES, FILLGS_BIN, FILLGS_SOURCE set."""
import gc
import json
import os
import re
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

import fillgs

FIXTURES = os.environ["FILLGS_MODEL_FIXTURES"]
CLI = os.environ["FILLGS_BIN"]
SOURCE = os.environ["FILLGS_SOURCE"]
# The fixtures' frame counts where their files do not say (tests/test_trained_models.cpp).
FRAMES = {"ed3dgs": 0, "4dgaussians": 10, "deformable3dgs": 9}
# Their last frame's model time (E-D3DGS and 4DGaussians: frame f at f / F; Deformable 3D
# Gaussians: f / (F - 1)), `fillgs info`'s "model times".
TIME_LAST = {"ed3dgs": 11 / 12, "4dgaussians": 0.9, "deformable3dgs": 1.0}


def fixture(name):
    return os.path.join(FIXTURES, name)


@pytest.fixture(scope="module")
def cameras_file(tmp_path_factory):
    path = str(tmp_path_factory.mktemp("cams") / "cameras.json")
    subprocess.run([sys.executable, os.path.join(SOURCE, "bench", "ring_cameras.py"), "6", path, "--wave"], check=True)
    return path


def cli(*args):
    r = subprocess.run([CLI, *args], capture_output=True, text=True)
    return r


def activated(state):
    q = state["quaternions"].astype(np.float64)
    return dict(means=state["means"], scales=np.exp(state["log_scales"].astype(np.float64)),
                rotations=q / np.linalg.norm(q, axis=1, keepdims=True),
                opacities=1 / (1 + np.exp(-state["opacity_logits"].astype(np.float64))),
                sh=state["sh"].reshape(state["sh"].shape[0], -1))


@pytest.mark.parametrize("name", ["ed3dgs", "4dgaussians", "deformable3dgs"])
def test_model_at_equals_pytorch(name):
    """Model.at(t) gives PyTorch's values (the fixture's expect.npz) at its times."""
    e = np.load(os.path.join(fixture(name), "expect.npz"))
    m = fillgs.load_model(fixture(name), frames=FRAMES[name], still_tolerance=0.0)
    assert m.size == e["means"].shape[1]
    for k, tau in enumerate(e["times"]):
        t = tau / TIME_LAST[name]  # at frames and between them: moving Gaussians are evaluated exactly
        a = activated(m.at(t))
        for key in ("means", "scales", "rotations", "opacities", "sh"):
            want = e[key][k]
            got = a[key]
            if key == "rotations":  # q and -q are one rotation
                got = got * np.sign((got * want).sum(axis=1, keepdims=True))
            np.testing.assert_allclose(got, want, rtol=1e-4, atol=2e-5, err_msg=f"{name} {key} at model time {tau}")


def test_model_formats_are_the_cli_table():
    """model_formats() is the command line's table: the names --scene-format takes, the format
    `fillgs info` detects for each fixture, and load_model(format=) reads it by that name."""
    formats = fillgs.model_formats()
    names = [f["name"] for f in formats]
    assert len(set(names)) == len(names) == 10
    help_text = cli("info", "--help").stdout
    for n in names:
        assert n in help_text
    for name in FRAMES:
        info = json.loads(cli("info", fixture(name), "--json", "--quiet", "--model-frames", str(FRAMES[name])).stdout)
        assert info["format"] in names
        assert [f["evaluated"] for f in formats if f["name"] == info["format"]] == [True]
        m = fillgs.load_model(fixture(name), format=info["format"], frames=FRAMES[name])
        assert m.size == info["gaussians"]
    with pytest.raises(fillgs.Error, match="unknown scene format 'no-such'.*e-d3dgs"):
        fillgs.load_model(fixture("ed3dgs"), format="no-such")


def test_format_parameters_are_keywords(tmp_path):
    """A format's own parameters, declared in its row, are load_model's keywords as they are the
    command line's flags: the value reaches the format, a bad one gets the command line's
    sentence in the keyword's name, and model_formats() lists them."""
    names = ["x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3",
             "trbf_center", "trbf_scale"] + [f"motion_{k}" for k in range(9)] + [f"omega_{k}" for k in range(4)]
    row = dict.fromkeys(names, 0.0)
    row.update(opacity=1.0, scale_0=-3.0, scale_1=-3.0, scale_2=-3.0, rot_0=1.0, trbf_center=0.5, trbf_scale=float(np.log(1000.0)), motion_0=1.0)
    path = tmp_path / "stg.ply"
    header = "ply\nformat binary_little_endian 1.0\nelement vertex 1\n" + "".join(f"property float {n}\n" for n in names) + "end_header\n"
    path.write_bytes(header.encode() + np.array([row[n] for n in names], dtype="<f4").tobytes())
    # x = (STG time) - 0.5 with frame f of D at STG time f / D: normalised time 1 is (D - 1) / D.
    assert fillgs.load_model(str(path), stg_duration=10).at(1.0)["means"][0, 0] == pytest.approx(0.9 - 0.5, abs=1e-6)
    assert fillgs.load_model(str(path)).at(1.0)["means"][0, 0] == pytest.approx(0.98 - 0.5, abs=1e-6)
    r = cli("info", str(path), "--stg-duration", "0")
    assert r.returncode != 0 and "--stg-duration must be in [1, 1e+06], got 0" in r.stderr, r.stderr
    with pytest.raises(fillgs.Error, match=r"^stg_duration must be in \[1, 1e\+06\], got 0$"):
        fillgs.load_model(str(path), stg_duration=0)
    with pytest.raises(TypeError, match="unexpected keyword argument 'stg_durations'.*stg_duration"):
        fillgs.load_model(str(path), stg_durations=10)
    with pytest.raises(TypeError, match="stg_color: expected a string"):
        fillgs.load_model(str(path), stg_color=1)
    stg = [f for f in fillgs.model_formats() if f["name"] == "stg"][0]
    assert stg["parameters"]["stg_duration"]["default"] == "50" and set(stg["parameters"]) == {"stg_duration", "stg_color"}
    external = [k for k in fillgs.refiners() if k["name"] == "external"][0]
    assert set(external["parameters"]) == {"refiner_command", "refiner_timeout"}


def test_model_arrays_layout():
    m = fillgs.load_model(fixture("ed3dgs"))
    s = m.at(0.5)
    n = m.size
    assert s["means"].shape == (n, 3) and s["means"].dtype == np.float32 and s["means"].flags.c_contiguous
    assert s["quaternions"].shape == (n, 4)
    assert s["sh"].shape == (n, (m.sh_degree + 1) ** 2, 3)
    assert m.dynamic_ids.dtype == np.uint32 and len(m.dynamic_ids) + m.static_count == n
    # The notes are what `fillgs info` prints.
    info = json.loads(cli("info", "--json", fixture("ed3dgs")).stdout)
    assert m.notes == info["notes"]
    assert m.frames == info["frames"]


@pytest.mark.parametrize("mode", ["frustum", "raytraced", "exact"])
def test_observe_equals_cli_files(tmp_path, cameras_file, mode):
    """observe() returns the tables `fillgs observe` writes, byte for byte."""
    name = "4dgaussians"
    out = str(tmp_path / "obs")
    r = cli("observe", "--scene", fixture(name), "--model-frames", "10", "--cameras", cameras_file, "--mode", mode, "--out", out, "--no-plots",
            "--tables", "dense", "--quiet")
    assert r.returncode == 0, r.stderr
    m = fillgs.load_model(fixture(name), frames=10)
    cams = fillgs.read_cameras(cameras_file)
    got = fillgs.observe(m, cams, mode=mode)
    for key, file in (("counts", "count.npy"), ("speed", "speed.npy"), ("deficiency", "deficiency.npy"), ("times", "times.npy"), ("dynamic_ids", "dynamic_ids.npy")):
        want = np.load(os.path.join(out, file))
        assert got[key].dtype == want.dtype, key
        assert got[key].shape == want.shape, key
        assert got[key].tobytes() == want.tobytes(), key
    # The compact layout (the default): numpy's reading of it by the documented recipe, and
    # load_observation's dense view, give the same tables.
    compact = str(tmp_path / "compact")
    r = cli("observe", "--scene", fixture(name), "--model-frames", "10", "--cameras", cameras_file, "--mode", mode, "--out", compact, "--no-plots", "--quiet")
    assert r.returncode == 0, r.stderr
    assert not os.path.exists(os.path.join(compact, "count.npy"))
    L = lambda f: np.load(os.path.join(compact, f + ".npy"))
    ids = L("dynamic_ids")
    counts = L("count_static")[L("count_rows")]
    counts[:, ids] = L("count_dynamic")
    offsets, change_ids, change_values = L("count_change_offsets"), L("count_change_ids"), L("count_change_values")
    for t in range(counts.shape[0]):
        s = slice(offsets[t], offsets[t + 1])
        counts[t, change_ids[s]] = change_values[s]
    assert counts.dtype == got["counts"].dtype and np.array_equal(counts, got["counts"])
    speed = np.zeros_like(got["speed"])
    speed[:, ids] = L("speed_dynamic")
    assert np.array_equal(speed, got["speed"])
    dense = fillgs.load_observation(compact, dense=True)
    for key in ("counts", "speed", "deficiency", "times", "dynamic_ids"):
        assert dense[key].dtype == got[key].dtype and dense[key].tobytes() == got[key].tobytes(), key
    stored = fillgs.load_observation(compact)
    assert stored["tables"] == "compact"
    for key in ("count_static", "count_rows", "count_dynamic", "count_change_offsets", "count_change_ids", "count_change_values", "speed_dynamic",
                "deficiency_dynamic"):
        assert stored[key].dtype == L(key).dtype and np.array_equal(stored[key], L(key)), key
    assert fillgs.load_observation(out)["tables"] == "dense"
    assert fillgs.load_observation(out, dense=True)["counts"].tobytes() == got["counts"].tobytes()


def test_still_rule_checks_the_jobs_times(tmp_path, cameras_file):
    """`fillgs observe --frames F` (or --times) tells a streamed model's still rule the times the
    job evaluates; fewer than its sweep's frames, those are checked and no others.
    load_model(still_times=...) gives Python the same model."""
    path = fixture("ed3dgs_still")  # 12 frames, 180 of 300 Gaussians still but for network noise
    full = fillgs.load_model(path)
    near_zero = fillgs.load_model(path, still_times=[0.0, 1e-6])
    assert len(full.dynamic_ids) == 120 and len(near_zero.dynamic_ids) == 0  # at t = 1e-6 nothing has moved yet
    assert any("each of the 1 other times the job evaluates" in n for n in near_zero.notes)
    assert not any("times the job evaluates" in n for n in full.notes)
    # Every Gaussian the job's rule calls still stays within the position tolerance at the
    # job's times, by the model's own values (every Gaussian moving: no still rule on position).
    every = fillgs.load_model(path, still_tolerance=0.0)
    assert len(every.dynamic_ids) == every.size
    for times in ([0.0, 1e-6], [0.0, 0.5, 1.0]):
        job = fillgs.load_model(path, still_times=times)
        still = np.setdiff1d(np.arange(job.size), job.dynamic_ids)
        assert len(still) > 0
        for t in times[1:]:
            moved = np.linalg.norm(every.at(t)["means"][still] - every.at(0.0)["means"][still], axis=1)
            assert moved.max() <= 1e-3 * (1 + 1e-6), (times, t)
    # The command line's `observe --frames 3` is observe() on the model read with those times.
    out = str(tmp_path / "obs")
    r = cli("observe", "--scene", path, "--cameras", cameras_file, "--frames", "3", "--tables", "dense", "--out", out, "--no-plots", "--quiet")
    assert r.returncode == 0, r.stderr
    got = fillgs.observe(fillgs.load_model(path, still_times=[0.0, 0.5, 1.0]), fillgs.read_cameras(cameras_file), frames=3)
    for key, file in (("counts", "count.npy"), ("speed", "speed.npy"), ("deficiency", "deficiency.npy"), ("dynamic_ids", "dynamic_ids.npy")):
        assert got[key].tobytes() == np.load(os.path.join(out, file)).tobytes(), key
    with pytest.raises(ValueError, match=r"still_times: element 1 is 1.5, not a time in \[0, 1\]"):
        fillgs.load_model(path, still_times=[0.0, 1.5])


def test_observe_some_frames_equals_cli(tmp_path, cameras_file):
    out = str(tmp_path / "obs")
    r = cli("observe", "--scene", fixture("ed3dgs"), "--cameras", cameras_file, "--frames", "4", "--out", out, "--no-plots", "--tables", "dense", "--quiet")
    assert r.returncode == 0, r.stderr
    got = fillgs.observe(fillgs.load_model(fixture("ed3dgs")), fillgs.read_cameras(cameras_file), frames=4)
    assert got["counts"].tobytes() == np.load(os.path.join(out, "count.npy")).tobytes()
    assert got["deficiency"].tobytes() == np.load(os.path.join(out, "deficiency.npy")).tobytes()


def test_observe_frame_function_equals_model(cameras_file):
    """The caller's Gaussians frame by frame (here the model's own, through Model.at) give the
    model's tables: positions are handed over exactly, so frustum counts, speeds and deficiency
    are equal to the bit."""
    m = fillgs.load_model(fixture("4dgaussians"), frames=10, still_tolerance=0.0)
    assert m.static_count == 0
    cams = fillgs.read_cameras(cameras_file)
    calls = []

    def frame(f):
        calls.append(f)
        return m.at(f / 9)

    for mode in ("frustum", "raytraced"):
        calls.clear()
        want = fillgs.observe(m, cams, mode=mode)
        got = fillgs.observe(frame, cams, frames=10, mode=mode, still_tolerance=0.0)
        for key in ("counts", "speed", "deficiency", "times"):
            assert got[key].tobytes() == want[key].tobytes(), (mode, key)
        assert sorted(set(calls)) == list(range(10)), mode
        # Each frame once, give or take the kept three (ray traced, the swept boxes asked for
        # every frame ahead of the walk: 21 calls for 10 frames).
        assert len(calls) <= 12, (mode, calls)


def test_observe_frame_function_still_rule(cameras_file):
    """A frame function's Gaussians go through load_model's still rule, seen once per frame: the
    network's raw frames (every Gaussian handed over moving) give the moving set, speeds and
    deficiency of the model read with the rule, the still ones static with zero speed."""
    raw = fillgs.load_model(fixture("ed3dgs_still"), still_tolerance=0.0)
    ruled = fillgs.load_model(fixture("ed3dgs_still"))
    F = raw.frames
    assert 0 < ruled.static_count < raw.size  # the fixture has both: the comparison is not vacuous
    cams = fillgs.read_cameras(cameras_file)
    got = fillgs.observe(lambda f: raw.at(f / (F - 1)), cams, frames=F)
    want = fillgs.observe(ruled, cams, frames=F)
    assert got["dynamic_ids"].tolist() == want["dynamic_ids"].tolist()
    for key in ("speed", "deficiency"):
        assert got[key].tobytes() == want[key].tobytes(), key
    everything = fillgs.observe(lambda f: raw.at(f / (F - 1)), cams, frames=F, still_tolerance=0.0)
    assert len(everything["dynamic_ids"]) == raw.size
    with pytest.raises(ValueError, match="still_tolerance"):
        fillgs.observe(ruled, cams, still_tolerance=1e-3)


def test_observe_frame_function_errors(cameras_file):
    m = fillgs.load_model(fixture("4dgaussians"), frames=10)
    cams = fillgs.read_cameras(cameras_file)

    def failing(f):
        if f == 3:
            raise KeyError("the caller's own error")
        return m.at(f / 9)

    with pytest.raises(KeyError, match="the caller's own error"):
        fillgs.observe(failing, cams, frames=10)

    def shrinking(f):
        s = m.at(f / 9)
        return {k: v[:-1] for k, v in s.items()} if f == 2 else s

    with pytest.raises(ValueError, match="frame 2 means: dimension 0 is 299, expected 300"):
        fillgs.observe(shrinking, cams, frames=10)


def test_cameras_read_and_from_arrays(cameras_file):
    cams = fillgs.read_cameras(cameras_file)
    a = cams.arrays()
    assert len(cams) == 6 and a["K"].shape == (6, 3, 3)
    # The file's camera-to-world (OpenGL axes) against the world-to-camera (OpenCV axes) given.
    doc = json.load(open(cameras_file))
    for i, fr in enumerate(doc["frames"]):
        c2w = np.array(fr["transform_matrix"], dtype=np.float64) @ np.diag([1, -1, -1, 1])
        np.testing.assert_allclose(np.linalg.inv(a["world_to_camera"][i]), c2w, atol=1e-9)
    assert np.all(np.isnan(a["time"]))
    again = fillgs.Cameras(a["K"], a["world_to_camera"], a["width"], a["height"], a["time"], cams.names)
    b = again.arrays()
    for k in a:
        np.testing.assert_allclose(b[k], a[k], rtol=1e-6, atol=1e-6, err_msg=k)
    assert again.names == cams.names


def single_gaussian(opacity_logit=0.0, dc=(1.0, 0.0, -1.0)):
    return dict(means=np.array([[0, 0, 5]], np.float32), log_scales=np.full((1, 3), np.log(0.5), np.float32),
                quaternions=np.array([[1, 0, 0, 0]], np.float32), opacity_logits=np.array([opacity_logit], np.float32),
                sh=np.array([[dc]], np.float32))


def test_render_one_gaussian_analytic():
    """A Gaussian on the optical axis: the centre pixel's alpha is its opacity, its colour
    0.5 + C0 SH_DC (clamped at 0) times that alpha, its blended depth z times alpha."""
    m = fillgs.model_from_arrays(single_gaussian(opacity_logit=0.4))
    cams = fillgs.Cameras(np.array([[[100, 0, 32], [0, 100, 24], [0, 0, 1]]], np.float64), np.eye(4)[None], 64, 48)
    r = fillgs.render(m, cams, 0)
    a = 1 / (1 + np.exp(-0.4))
    assert r["colour"].shape == (48, 64, 3) and r["alpha"].shape == (48, 64)
    # The pixel centre (32.5, 24.5) is half a pixel off the projected centre (32, 24): the
    # screen-space Gaussian's weight there, with its 0.3 px^2 dilation.
    var = (100 * 0.5 / 5) ** 2 + 0.3
    w = np.exp(-0.5 * (0.25 + 0.25) / var)
    assert r["alpha"][24, 32] == pytest.approx(a * w, rel=1e-3)
    c0 = 0.28209479177387814
    want = np.maximum(0.0, 0.5 + c0 * np.array([1.0, 0.0, -1.0])) * a * w
    np.testing.assert_allclose(r["colour"][24, 32], want, rtol=1e-3, atol=1e-5)
    assert r["depth"][24, 32] == pytest.approx(5 * a * w, rel=1e-3)
    assert r["alpha"][0, 0] < 1e-6


@pytest.mark.parametrize("channel", ["rgb", "alpha"])
def test_render_equals_cli(tmp_path, cameras_file, channel):
    """render() draws what `fillgs render` writes (float EXR: to the bit), for a streamed
    network model at a time between its frames, every camera."""
    out = str(tmp_path / "render")
    r = cli("render", "--scene", fixture("4dgaussians"), "--model-frames", "10", "--cameras", cameras_file, "--time", "0.37",
            "--channel", channel, "--format", "exr", "--out", out, "--quiet")
    assert r.returncode == 0, r.stderr
    m = fillgs.load_model(fixture("4dgaussians"), frames=10)
    cams = fillgs.read_cameras(cameras_file)
    names = cams.names
    assert len(names) == 6
    for i, name in enumerate(names):
        got = fillgs.render(m, cams, index=i, t=0.37)["colour" if channel == "rgb" else "alpha"]
        want = fillgs.read_image(os.path.join(out, name + ".exr"))
        want = want if channel == "rgb" else want[:, :, 0]
        assert got.shape == want.shape, name
        assert got.tobytes() == want.tobytes(), name
        assert got.max() > 0, name  # the camera sees the model


def test_errors_carry_the_cli_message(tmp_path):
    bad = fixture("broken_shape")
    r = cli("info", bad)
    assert r.returncode != 0
    line = r.stderr.strip().splitlines()[-1]
    with pytest.raises(fillgs.Error) as e:
        fillgs.load_model(bad)
    assert isinstance(e.value, ValueError)
    assert str(e.value) in line
    with pytest.raises(FileNotFoundError, match="nowhere"):
        fillgs.load_model(str(tmp_path / "nowhere"))
    with pytest.raises(fillgs.Error, match="unknown scene format 'nope'"):
        fillgs.load_model(fixture("ed3dgs"), format="nope")


def test_bad_arrays_raise():
    good = single_gaussian()
    fillgs.model_from_arrays(good)
    with pytest.raises(ValueError, match="means: dimension 1 is 2, expected 3"):
        fillgs.model_from_arrays(dict(good, means=np.zeros((1, 2), np.float32)))
    with pytest.raises(ValueError, match="log_scales: dimension 0 is 2, expected 1"):
        fillgs.model_from_arrays(dict(good, log_scales=np.zeros((2, 3), np.float32)))
    with pytest.raises(TypeError, match="opacity_logits: expected real numbers"):
        fillgs.model_from_arrays(dict(good, opacity_logits=np.array(["a"])))
    with pytest.raises(ValueError, match="means: element 0 is not finite"):
        fillgs.model_from_arrays(dict(good, means=np.array([[0, np.nan, 5]], np.float32)))
    with pytest.raises(ValueError, match="quaternions: element 0 is zero"):
        fillgs.model_from_arrays(dict(good, quaternions=np.zeros((1, 4), np.float32)))
    with pytest.raises(KeyError):
        fillgs.model_from_arrays({"means": good["means"]})
    with pytest.raises(ValueError, match="sh: 2 coefficients"):
        fillgs.model_from_arrays(dict(good, sh=np.zeros((1, 2, 3), np.float32)))
    with pytest.raises(ValueError, match="cameras: element 0 has a rotation that is not one"):
        fillgs.Cameras(np.diag([100.0, 100.0, 1.0])[None], np.diag([2.0, 1, 1, 1])[None], 64, 48)
    with pytest.raises(ValueError, match="width: element 0 is not a pixel count"):
        fillgs.Cameras(np.diag([100.0, 100.0, 1.0])[None], np.eye(4)[None], 0, 48)
    # Non-contiguous and float64 arrays are copied once and give the same model.
    wide = np.zeros((1, 6), np.float64)
    wide[:, ::2] = good["means"]
    m = fillgs.model_from_arrays(dict(good, means=wide[:, ::2]))
    assert m.at(0)["means"].tobytes() == good["means"].tobytes()


def test_the_gil_is_released_during_observe(cameras_file):
    """Another Python thread advances while one observe call runs: held, the GIL would let it
    run only at the call's start (one switch interval, 5 ms)."""
    m = fillgs.load_model(fixture("ed3dgs"))
    cams = fillgs.read_cameras(cameras_file)
    ticks = [0]
    stop = threading.Event()

    def spin():
        while not stop.is_set():
            ticks[0] += 1

    t = threading.Thread(target=spin)
    t.start()
    try:
        time.sleep(0.2)
        start, before = time.perf_counter(), ticks[0]
        time.sleep(0.2)
        rate = (ticks[0] - before) / (time.perf_counter() - start)  # ticks a second, the thread alone
        start, before = time.perf_counter(), ticks[0]
        fillgs.observe(m, cams, frames=600, mode="raytraced")
        seconds = time.perf_counter() - start
        during = ticks[0] - before
    finally:
        stop.set()
        t.join()
    assert seconds > 0.2, seconds  # long enough to tell
    assert during > 0.05 * rate * seconds, (during, rate, seconds)


def test_no_reference_leaks():
    good = single_gaussian()
    means = good["means"]
    m = fillgs.model_from_arrays(good)
    cams = fillgs.Cameras(np.diag([100.0, 100.0, 1.0])[None], np.eye(4)[None], 64, 48)
    for _ in range(20):
        fillgs.model_from_arrays(good), m.at(0), fillgs.render(m, cams, 0)
    gc.collect()
    refs, objects = sys.getrefcount(means), len(gc.get_objects())
    for _ in range(1000):
        fillgs.model_from_arrays(good)
        m.at(0.0)
        cams.arrays()
        fillgs.render(m, cams, 0)
    gc.collect()
    assert sys.getrefcount(means) == refs
    assert len(gc.get_objects()) <= objects + 10


def test_progress_callback(cameras_file):
    seen = []
    fillgs.observe(fillgs.load_model(fixture("ed3dgs")), fillgs.read_cameras(cameras_file), progress=lambda label, done, total: seen.append((label, done, total)))
    assert seen and seen[-1][0] == "observe" and seen[-1][1] == seen[-1][2] == 12


@pytest.fixture(scope="module")
def synth(tmp_path_factory):
    """fillgs synth's small scene: a model with moving Gaussians, timed training cameras, images."""
    d = str(tmp_path_factory.mktemp("synth") / "scene")
    r = cli("synth", "--out", d, "--frames", "3", "--width", "48", "--height", "36", "--spacing", "0.06", "--quiet")
    assert r.returncode == 0, r.stderr
    return d


def test_explore_equals_cli_grid(tmp_path, synth):
    """explore's labels are those of the exploration.vdb `fillgs explore` writes; label_at reads them."""
    out = str(tmp_path / "explore")
    r = cli("explore", "--scene", f"{synth}/scene.ply", "--cameras", f"{synth}/transforms_train.json", "--out", out, "--quiet")
    assert r.returncode == 0, r.stderr
    want = fillgs.read_grid(f"{out}/exploration.vdb")
    got = fillgs.explore(fillgs.load_model(f"{synth}/scene.ply"), fillgs.read_cameras(f"{synth}/transforms_train.json"))
    assert got.dims == want.dims == [64, 64, 64]
    np.testing.assert_allclose(got.box[0], want.box[0], rtol=1e-6)
    labels = got.labels
    assert labels.dtype == np.uint8 and labels.shape == (64, 64, 64)
    assert np.array_equal(labels, want.labels)
    assert set(np.unique(labels)) <= {0, 1, 2} and (labels == 1).any() and (labels == 0).any()
    # label_at: a voxel's centre gets that voxel's label.
    lo, hi = np.array(got.box[0]), np.array(got.box[1])
    size = (hi - lo) / 64
    zyx = np.argwhere(labels == 1)[:5]
    centres = lo + (zyx[:, ::-1] + 0.5) * size
    assert (got.label_at(centres) == 1).all()
    assert got.label_at(np.array([hi + 10 * size]))[0] == 2  # outside the box: unexplored


@pytest.mark.parametrize("strategy", ["fillgs", "coverage4d"])
def test_select_equals_cli(tmp_path, synth, strategy):
    """select's trajectories are the CLI's: the same virtual cameras (transforms.json) and scores."""
    out = str(tmp_path / "select")
    r = cli("select", "--scene", f"{synth}/scene.ply", "--cameras", f"{synth}/transforms_train.json", "--out", out, "--trajectories", "2",
            "--seed", "3", "--strategy", strategy, "--no-renders", "--quiet")
    assert r.returncode == 0, r.stderr
    model = fillgs.load_model(f"{synth}/scene.ply")
    cams = fillgs.read_cameras(f"{synth}/transforms_train.json")
    sel = fillgs.select(model, cams, trajectories=2, seed=3, strategy=strategy)
    trajs = sel["trajectories"]
    ref = json.load(open(f"{out}/trajectories.json"))
    assert len(trajs) == len(ref["trajectories"]) == 2
    assert sel["deficiency_scale"] == pytest.approx(ref["deficiency_scale"], rel=1e-6)
    for t, w in zip(trajs, ref["trajectories"]):
        assert t.index == w["index"] and t.frame == w["frame"] and t.is_global == w["global"]
        assert list(t.patch_frames) == w["patch_frames"]
        np.testing.assert_allclose(t.scores, [p["score"] for p in w["poses"]], rtol=1e-9)
    got = [t.views().arrays() for t in trajs]
    want = fillgs.read_cameras(f"{out}/transforms.json").arrays()
    for key in ("K", "world_to_camera", "time"):
        np.testing.assert_allclose(np.concatenate([g[key] for g in got]), want[key], atol=1e-9, err_msg=key)


def test_load_views_frame_range_keeps_the_videos_times(synth):
    """A frame range keeps each view's time in the whole video (the model's frames), its frame
    count and each view's frame in it, instead of re-timing the kept frames as a video of their own."""
    full = fillgs.load_views(synth, f"{synth}/transforms_train.json")
    some = fillgs.load_views(synth, f"{synth}/transforms_train.json", frames="1::2")
    assert some["frames"] == full["frames"] and full["frames"] >= 3
    times = {}
    for name, t, f in zip(full["cameras"].names, full["cameras"].arrays()["time"], full["source_frames"]):
        assert t == pytest.approx(f / (full["frames"] - 1))
        times[(name, int(f))] = t
    assert len(some["images"]) and set(some["source_frames"].tolist()) == set(range(1, full["frames"], 2))
    for name, t, f in zip(some["cameras"].names, some["cameras"].arrays()["time"], some["source_frames"]):
        assert t == times[(name, int(f))]


@pytest.mark.parametrize("flags, keywords", [([], {}),
                                             (["--mask-sigma", "0.2", "--covis-scale", "global", "--covis", "density"],
                                              dict(mask_sigma=0.2, covis_scale="global", covis="density"))])
def test_weights_equal_finetune_maps(tmp_path, synth, flags, keywords):
    """weights() gives the weight maps `fillgs finetune` writes beside each refined image (8-bit),
    with finetune's options as keywords."""
    out = str(tmp_path / "ft")
    script = os.path.join(SOURCE, "scripts", "refiners", "median_denoise.sh")
    r = cli("finetune", "--model", f"{synth}/scene.ply", "--images", synth, "--cameras", f"{synth}/transforms_train.json",
            "--train-cameras", "cam04,cam06", "--out", out, "--iterations", "10", "--select-every", "10", "--trajectories", "1",
            "--refiner", "external", "--refiner-command", f"bash {script} {{in}} {{out}}", "--quiet", *flags)
    assert r.returncode == 0, r.stderr
    views = fillgs.load_views(synth, f"{synth}/transforms_train.json", train_cameras=["cam04", "cam06"])
    assert len(views["images"]) == 6 and views["images"][0].shape == (36, 48, 3) and views["images"][0].dtype == np.uint8  # as held, not copied to float
    patch = json.load(open(f"{out}/work/patches/r0_t00/patch.json"))
    items = [im for im in patch["images"] if not im["observed"]]
    assert items
    c2w = np.array([im["camera"]["camera_to_world_opencv"] for im in items])
    K = np.array([[[im["camera"]["fx"], 0, im["camera"]["cx"]], [0, im["camera"]["fy"], im["camera"]["cy"]], [0, 0, 1]] for im in items])
    refined_cams = fillgs.Cameras(K, np.linalg.inv(c2w), 48, 36, time=np.array([im["time"] for im in items]))
    stems = [f"{out}/work/refined/r0_t00/{os.path.splitext(im['file'])[0]}" for im in items]
    refined = [fillgs.read_image(s + ".png") for s in stems]
    got = fillgs.weights(fillgs.load_model(f"{synth}/scene.ply"), views["cameras"], views["images"], refined, refined_cams, weighting="fillgs",
                         **keywords)
    assert len(got) == len(items)
    if keywords:  # the options change the maps (else the comparison below proves nothing about them)
        plain = fillgs.weights(fillgs.load_model(f"{synth}/scene.ply"), views["cameras"], views["images"], refined, refined_cams)
        assert any(np.abs(a["weight"] - b["weight"]).max() > 2 / 255 for a, b in zip(got, plain))
        scaled = fillgs.weights(fillgs.load_model(f"{synth}/scene.ply"), views["cameras"], views["images"], refined, refined_cams,
                                normalise=True, **keywords)
        for a, b in zip(scaled, got):
            if b["weight"].mean() > 0:
                assert a["weight"] == pytest.approx(b["weight"] / b["weight"].mean(), rel=1e-5, abs=1e-6)
        with pytest.raises(fillgs.Error, match="mask_sigma must be positive, got 0"):
            fillgs.weights(fillgs.load_model(f"{synth}/scene.ply"), views["cameras"], views["images"], refined, refined_cams, mask_sigma=0)
        return
    for g, s in zip(got, stems):
        for key, suffix in (("weight", "_weight.png"), ("consistency", "_mask.png"), ("covisibility", "_covis.png")):
            want = fillgs.read_image(s + suffix)[:, :, 0]
            assert g[key].shape == want.shape
            assert np.abs(g[key] - want).max() <= 0.5 / 255 + 1e-6, f"{s}{suffix}"
    # The views as floats in [0, 1] give the same maps, to the bit, as the 8-bit views.
    as_float = fillgs.weights(fillgs.load_model(f"{synth}/scene.ply"), views["cameras"], [im.astype(np.float32) / 255 for im in views["images"]],
                              refined, refined_cams)
    for a, b in zip(as_float, got):
        assert a["weight"].tobytes() == b["weight"].tobytes()
    # observe()'s tables handed over give the same maps, to the bit; another frame count is refused.
    model = fillgs.load_model(f"{synth}/scene.ply")
    tables = fillgs.observe(model, views["cameras"], frames=views["frames"])
    again = fillgs.weights(model, views["cameras"], views["images"], refined, refined_cams, tables=tables)
    for a, b in zip(again, got):
        for key in ("weight", "consistency", "covisibility"):
            assert a[key].tobytes() == b[key].tobytes(), key
    with pytest.raises(fillgs.Error, match="tables: 2 times, not the 3 frames of the views"):
        fillgs.weights(model, views["cameras"], views["images"], refined, refined_cams, tables=fillgs.observe(model, views["cameras"], frames=2))
    # No weights: every pixel counts 1.
    none = fillgs.weights(fillgs.load_model(f"{synth}/scene.ply"), views["cameras"], views["images"], refined[:1],
                          fillgs.Cameras(K[:1], np.linalg.inv(c2w[:1]), 48, 36, time=np.array([items[0]["time"]])), weighting="none")
    assert (none[0]["weight"] == 1).all() and none[0]["consistency"] is None
    with pytest.raises(ValueError, match="refined: 2 images for 1 views"):
        fillgs.weights(fillgs.load_model(f"{synth}/scene.ply"), views["cameras"], views["images"], refined[:2],
                       fillgs.Cameras(K[:1], np.linalg.inv(c2w[:1]), 48, 36, time=np.array([items[0]["time"]])))


def test_instruction_set_read_at_import():
    """FILLGS_INSTRUCTION_SET holds the kernels from import on, as the command line's `--version` says; a bad value is
    the command line's one line, at import."""
    def run(value, code):
        env = dict(os.environ)
        env.pop("FILLGS_INSTRUCTION_SET", None)
        if value is not None:
            env["FILLGS_INSTRUCTION_SET"] = value
        return subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
    widest = run(None, "import fillgs; print(fillgs.instruction_set()['kernels'])").stdout.strip()
    assert widest == fillgs.instruction_set()["kernels"]
    cli = subprocess.run([CLI, "--version"], capture_output=True, text=True, env={k: v for k, v in os.environ.items() if k != "FILLGS_INSTRUCTION_SET"})
    assert f"kernels: {widest} (the CPU's widest)" in cli.stdout
    held = run("sse4", "import fillgs, json; print(json.dumps(fillgs.instruction_set()))")
    assert held.returncode == 0, held.stderr
    assert json.loads(held.stdout) == {"kernels": "SSE4", "held_to": "sse4"}
    bad = run("avx9", "import fillgs")
    assert bad.returncode != 0
    assert "FILLGS_INSTRUCTION_SET: 'avx9' is not an instruction set fillgs can be held to (avx512, avx2, sse4 or native)" in bad.stderr


def test_finetune_is_the_command_lines_job(tmp_path, synth):
    """fillgs.finetune runs `fillgs finetune`'s job: on the same scene, views and options it
    chooses the same pool photographs and writes the same model, byte for byte; a bad
    combination gets the command line's sentence with the keywords' names."""
    common = ["--model", f"{synth}/scene.ply", "--images", synth, "--cameras", f"{synth}/transforms_train.json", "--train-cameras", "cam04,cam06",
              "--iterations", "20", "--select-every", "10", "--pool-cameras", "cam05,cam07", "--pool-budget", "4", "--strategy", "coverage4d",
              "--weighting", "none", "--quiet"]
    out_cli, out_py = str(tmp_path / "cli"), str(tmp_path / "py")
    r = cli("finetune", *common, "--out", out_cli)
    assert r.returncode == 0, r.stderr
    kw = dict(train_cameras=["cam04", "cam06"], iterations=20, select_every=10, pool_cameras=["cam05", "cam07"], pool_budget=4,
              strategy="coverage4d", weighting="none")
    model = fillgs.load_model(f"{synth}/scene.ply")
    summary = fillgs.finetune(model, synth, f"{synth}/transforms_train.json", out_py, **kw)
    assert summary == json.load(open(os.path.join(out_py, "summary.json")))
    assert summary["refiner"] == "pool" and summary["virtual_views"] == 4
    chosen = [json.load(open(os.path.join(d, "pool_chosen.json")))["chosen"] for d in (out_cli, out_py)]
    assert [(c["camera"], c["frame"]) for c in chosen[0]] == [(c["camera"], c["frame"]) for c in chosen[1]]
    assert open(os.path.join(out_cli, "model.ply"), "rb").read() == open(os.path.join(out_py, "model.ply"), "rb").read()
    # The same check, each face's spelling of the options.
    bad = cli("finetune", *common, "--refiner", "identity", "--out", str(tmp_path / "bad_cli"))
    assert bad.returncode != 0 and "--pool-budget adds the pool's own photographs: it takes no --refiner" in bad.stderr, bad.stderr
    with pytest.raises(Exception, match="pool_budget adds the pool's own photographs: it takes no refiner"):
        fillgs.finetune(model, synth, f"{synth}/transforms_train.json", str(tmp_path / "bad_py"), refiner="identity", **kw)
    assert not os.path.exists(tmp_path / "bad_cli") and not os.path.exists(tmp_path / "bad_py")
    with pytest.raises(Exception, match="refined_share must be in"):
        fillgs.finetune(model, synth, f"{synth}/transforms_train.json", str(tmp_path / "bad_py"), refined_share=2.0, **kw)
    # A refiner's own parameter (declared in its row) is a keyword too, checked as its flag is.
    no_pool = {k: v for k, v in kw.items() if k not in ("pool_cameras", "pool_budget")}
    bad = cli("finetune", *common[:-9], "--quiet", "--refiner", "external", "--out", str(tmp_path / "bad_cli"))
    assert bad.returncode != 0 and "missing --refiner-command" in bad.stderr, bad.stderr
    with pytest.raises(fillgs.Error, match="^missing refiner_command$"):
        fillgs.finetune(model, synth, f"{synth}/transforms_train.json", str(tmp_path / "bad_py"), refiner="external", **no_pool)
    with pytest.raises(fillgs.Error, match=r"^refiner_timeout must be positive, got 0$"):
        fillgs.finetune(model, synth, f"{synth}/transforms_train.json", str(tmp_path / "bad_py"), refiner="external", refiner_command="x {in} {out}",
                        refiner_timeout=0, **no_pool)
    assert not os.path.exists(tmp_path / "bad_cli") and not os.path.exists(tmp_path / "bad_py")
    # The options several refiners share: keywords too, the job's one check.
    for flag, keyword, value, words in [("--support-window", "support_window", -1, "must be at least 0, got -1"),
                                        ("--reference-angle", "reference_angle", 0, "must be positive, got 0"),
                                        ("--artifact-strength", "artifact_strength", -0.5, "must be at least 0, got -0.5")]:
        bad = cli("finetune", *common[:-9], "--quiet", "--refiner", "identity", flag, str(value), "--out", str(tmp_path / "bad_cli"))
        assert bad.returncode != 0 and f"{flag} {words}" in bad.stderr, bad.stderr
        with pytest.raises(fillgs.Error, match="^" + re.escape(f"{keyword} {words}") + "$"):
            fillgs.finetune(model, synth, f"{synth}/transforms_train.json", str(tmp_path / "bad_py"), refiner="identity", **{keyword: value}, **no_pool)
    assert not os.path.exists(tmp_path / "bad_cli") and not os.path.exists(tmp_path / "bad_py")


def test_select_options_get_the_command_lines_check(tmp_path, cameras_file):
    """select's counts and ablations are checked once, in the library (check_select_options,
    with the bounds the command line's flags declare), and explore's and observe's against the
    bounds declared beside their options: the same sentence from either face."""
    scene = fixture("ed3dgs")
    m, cams = fillgs.load_model(scene), fillgs.read_cameras(cameras_file)
    for flag, keyword, value, words in [("--trajectories", "trajectories", 100001, "must be in [0, 100000], got 100001"),
                                        ("--views", "views", 0, "must be in [1, 1000], got 0"),
                                        ("--patch-frames", "patch_frames", 1001, "must be in [1, 1000], got 1001")]:
        r = cli("select", "--scene", scene, "--cameras", cameras_file, "--out", str(tmp_path / "s"), flag, str(value), "--quiet")
        assert r.returncode != 0 and f"{flag} {words}" in r.stderr, r.stderr
        with pytest.raises(fillgs.Error, match="^" + re.escape(f"{keyword} {words}") + "$"):
            fillgs.select(m, cams, frames=5, **{keyword: value})
    with pytest.raises(fillgs.Error, match="unknown strategy 'greedy'"):
        fillgs.select(m, cams, frames=5, strategy="greedy")
    assert not os.path.exists(tmp_path / "s")
    # explore's and observe's bounds: declared once beside their options, the same words.
    r = cli("explore", "--scene", scene, "--cameras", cameras_file, "--out", str(tmp_path / "e"), "--divisions", "0", "--quiet")
    assert r.returncode != 0 and "--divisions must be at least 1, got 0" in r.stderr, r.stderr
    with pytest.raises(fillgs.Error, match=r"^divisions must be at least 1, got 0$"):
        fillgs.explore(m, cams, frames=5, divisions=0)
    r = cli("observe", "--scene", scene, "--cameras", cameras_file, "--frames", "5", "--out", str(tmp_path / "o"), "--tau", "1", "--quiet")
    assert r.returncode != 0 and "--tau must be in (0, 1), got 1" in r.stderr, r.stderr
    with pytest.raises(fillgs.Error, match=r"^tau must be in \(0, 1\), got 1$"):
        fillgs.observe(m, cams, frames=5, tau=1.0)


def test_observe_options_get_the_command_lines_check(tmp_path, cameras_file):
    """frames and times are checked once, in the library (observe_times): the command line and
    the module say the same sentence, each naming the option its own way; unsorted times with
    a repeat are taken as the command line takes them (sorted, once each)."""
    scene = fixture("ed3dgs")
    r = cli("observe", "--scene", scene, "--cameras", cameras_file, "--frames", "5", "--times", "0.5,2", "--out", str(tmp_path / "o1"), "--quiet")
    assert r.returncode != 0 and "--times: element 1 is 2, not a time in [0, 1]" in r.stderr, r.stderr
    m, cams = fillgs.load_model(scene), fillgs.read_cameras(cameras_file)
    with pytest.raises(fillgs.Error, match=r"^times: element 1 is 2, not a time in \[0, 1\]$"):
        fillgs.observe(m, cams, frames=5, times=[0.5, 2.0])
    r = cli("observe", "--scene", scene, "--cameras", cameras_file, "--frames", "1", "--times", "0.5", "--out", str(tmp_path / "o2"), "--quiet")
    assert r.returncode != 0 and "give --frames F with --times (the speed's step is one frame, 1/(F-1))" in r.stderr, r.stderr
    with pytest.raises(fillgs.Error, match=r"give frames F with times \(the speed's step is one frame"):
        fillgs.observe(m, cams, frames=1, times=[0.5])
    got = fillgs.observe(m, cams, frames=5, times=[0.75, 0.25, 0.75])
    out = str(tmp_path / "o3")
    r = cli("observe", "--scene", scene, "--cameras", cameras_file, "--frames", "5", "--times", "0.75,0.25,0.75", "--out", out, "--no-plots",
            "--tables", "dense", "--quiet")
    assert r.returncode == 0, r.stderr
    assert list(got["times"]) == [0.25, 0.75] and np.array_equal(np.load(os.path.join(out, "times.npy")), got["times"])
    assert np.array_equal(np.load(os.path.join(out, "count.npy")), got["counts"])
