"""The Python face checks what the command line checks, and stops when asked: each case is a
value the command line refuses (or a camera its readers refuse), given as arrays or keywords,
which must raise naming the keyword and never crash, clamp, or turn into the default; and
Ctrl-C or a callback's own exception must stop a long call at once, unchanged.

Run by CTest's python_module with test_module.py (same environment)."""
import _thread
import os
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

import fillgs

FIXTURES = os.environ["FILLGS_MODEL_FIXTURES"]
CLI = os.environ["FILLGS_BIN"]


def one_gaussian():
    return dict(means=np.array([[0, 0, 5]], np.float32), log_scales=np.full((1, 3), -2, np.float32),
                quaternions=np.array([[1, 0, 0, 0]], np.float32), opacity_logits=np.zeros(1, np.float32))


def pinhole(n=1):
    return np.tile(np.array([[100.0, 0, 32], [0, 100, 24], [0, 0, 1]]), (n, 1, 1))


def camera_at(**changes):
    """K and world_to_camera of one camera, with entries changed: {"K": {(0, 2): 1e30}}."""
    K, M = pinhole(), np.eye(4)[None].copy()
    for (i, j), v in changes.get("K", {}).items():
        K[0, i, j] = v
    for (i, j), v in changes.get("M", {}).items():
        M[0, i, j] = v
    return K, M


@pytest.mark.parametrize("change, words", [
    ({"M": {(0, 3): 2e18}}, "cameras: element 0 stands at"),           # aborted the interpreter in Embree before
    ({"K": {(0, 2): 1e30}}, "cameras: element 0 has principal point"),
    ({"K": {(0, 0): 1e12}}, "cameras: element 0 has focal length"),
    ({"K": {(0, 1): 0.5}}, "K: element 0 is not a pinhole matrix"),    # skew was dropped
    ({"K": {(2, 2): 2.0}}, "K: element 0 is not a pinhole matrix"),    # K[2,2] was dropped
    ({"M": {(3, 0): 1.0}}, "world_to_camera: element 0 has last row"),  # the pose's last row was dropped
])
def test_cameras_from_arrays_take_the_readers_bounds(change, words):
    K, M = camera_at(**change)
    with pytest.raises(fillgs.Error, match=words):
        fillgs.Cameras(K, M, 64, 48)


def test_far_camera_refused_before_the_tracer(tmp_path):
    """The case that aborted: a camera 2e18 away reaching observe(mode="raytraced"); the same
    camera in a transforms.json is refused by the command line's reader in the same words."""
    K, M = camera_at(M={(0, 3): 2e18})
    with pytest.raises(fillgs.Error) as e:
        fillgs.Cameras(K, M, 64, 48)
    path = tmp_path / "transforms.json"
    c2w = np.linalg.inv(np.diag([1.0, -1, -1, 1]) @ np.eye(4))  # OpenGL axes, as transforms.json stores them
    c2w[0, 3] = -2e18
    path.write_text('{"frames": [{"file_path": "a", "fl_x": 100, "fl_y": 100, "cx": 32, "cy": 24, "w": 64, "h": 48, '
                    f'"transform_matrix": {c2w.tolist()}}}]}}')
    with pytest.raises(fillgs.Error) as read:
        fillgs.read_cameras(str(path))  # the command line's reader
    for message in (str(e.value), str(read.value)):
        assert "stands at (-2e+18, " in message and "beyond 1e+07 world units from the origin" in message


def test_names_must_match_the_cameras():
    with pytest.raises(fillgs.Error, match="names: 1 names for 2 cameras"):
        fillgs.Cameras(pinhole(2), np.tile(np.eye(4), (2, 1, 1)), 64, 48, names=["a"])
    assert fillgs.Cameras(pinhole(2), np.tile(np.eye(4), (2, 1, 1)), 64, 48, names=["a", "b"]).names == ["a", "b"]


@pytest.fixture(scope="module")
def scene():
    m = fillgs.model_from_arrays(one_gaussian())
    return m, fillgs.Cameras(pinhole(), np.eye(4)[None], 64, 48)


@pytest.mark.parametrize("keyword, value, words", [
    ("tau", float("nan"), "tau expects a number, got nan"),
    ("tau", -0.5, "tau must be in \\(0, 1\\), got -0.5"),
    ("hit_cache_mb", float("inf"), "hit_cache_mb expects a number, got inf"),
    ("hit_cache_mb", -1.0, "hit_cache_mb must be in \\[0, 1e\\+09\\), got -1"),
])
def test_observe_options_refused_not_defaulted(scene, keyword, value, words):
    m, cams = scene
    with pytest.raises(fillgs.Error, match=words):
        fillgs.observe(m, cams, frames=2, **{keyword: value})
    fillgs.observe(m, cams, frames=2, tau=0.5, hit_cache_mb=0)  # good values still pass


def test_command_line_gives_the_same_words(tmp_path):
    r = subprocess.run([CLI, "observe", "--scene", "x.ply", "--cameras", "y.json", "--out", str(tmp_path / "o"), "--tau", "-0.5"],
                       capture_output=True, text=True)
    assert r.returncode != 0 and "--tau must be in (0, 1), got -0.5" in r.stderr


@pytest.mark.parametrize("value, words", [(float("nan"), "still_tolerance expects a number, got nan"),
                                          (float("inf"), "still_tolerance expects a number, got inf"),
                                          (-1.0, "still_tolerance must be at least 0, got -1")])
def test_still_tolerance_refused_not_defaulted(value, words):
    with pytest.raises(fillgs.Error, match=words):
        fillgs.load_model(os.path.join(FIXTURES, "ed3dgs"), still_tolerance=value)


def test_model_frames_take_the_flags_bounds():
    with pytest.raises(fillgs.Error, match="frames must be at least 0, got -5"):  # was read as "from cfg_args"
        fillgs.load_model(os.path.join(FIXTURES, "ed3dgs"), frames=-5)


def test_render_background_and_times(scene):
    m, cams = scene
    with pytest.raises(fillgs.Error, match=r"background\[0\] expects a number, got nan"):
        fillgs.render(m, cams, background=[float("nan"), 0, 0])
    with pytest.raises(fillgs.Error, match=r"background\[1\] must be in \[0, 1\], got 2"):
        fillgs.render(m, cams, background=[0, 2, 0])
    with pytest.raises(fillgs.Error, match=r"t must be in \[0, 1\], got 5"):
        m.at(5.0)  # clamped to 1 before, where render refuses
    with pytest.raises(fillgs.Error, match=r"t expects a number, got nan"):
        fillgs.render(m, cams, t=float("nan"))  # the same words as Model.at
    assert np.isfinite(fillgs.render(m, cams, background=[0.2, 0.3, 0.4])["colour"]).all()


def test_sh_without_coefficients_refused():
    with pytest.raises(ValueError, match="sh: 0 coefficients per Gaussian"):
        fillgs.model_from_arrays(dict(one_gaussian(), sh=np.zeros((1, 0, 3), np.float32)))


def test_select_grid_of_the_wrong_type(scene):
    m, cams = scene
    with pytest.raises(TypeError, match="grid: expected a fillgs.ExplorationGrid"):
        fillgs.select(m, cams, frames=2, grid=5)


def test_explore_of_an_empty_model_names_why(scene):
    _, cams = scene
    empty = fillgs.model_from_arrays({k: v[:0] for k, v in one_gaussian().items()})
    with pytest.raises(fillgs.Error, match="exploration grid: nothing to span: the model has no Gaussians"):
        fillgs.explore(empty, cams)


# ------------------------------------------------------------------ stopping a long call

def test_a_callbacks_exception_passes_through_unchanged():
    class Mine(Exception):
        pass

    def raising(label, done, total):
        raise Mine("from the callback")

    with pytest.raises(Mine, match="from the callback"):  # was fillgs.Error "...: malformed (Mine: ...)"
        fillgs.load_model(os.path.join(FIXTURES, "ed3dgs"), progress=raising)

    def interrupting(label, done, total):
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        fillgs.load_model(os.path.join(FIXTURES, "ed3dgs"), progress=interrupting)
    fillgs.load_model(os.path.join(FIXTURES, "ed3dgs"))  # and the next call is unaffected


def test_ctrl_c_stops_observe_within_a_second(tmp_path):
    """Ctrl-C (here _thread.interrupt_main, what the terminal's SIGINT does) sent 0.5 s into an
    observe call of a loaded model, no callback: it stops at the next frame, not at the end."""
    m = fillgs.load_model(os.path.join(FIXTURES, "ed3dgs"))
    path = str(tmp_path / "cameras.json")
    subprocess.run([sys.executable, os.path.join(os.environ["FILLGS_SOURCE"], "bench", "ring_cameras.py"), "6", path, "--wave"], check=True)
    cams = fillgs.read_cameras(path)
    start = time.perf_counter()
    fillgs.observe(m, cams, frames=400, mode="raytraced")
    per_frame = (time.perf_counter() - start) / 400
    frames = int(min(200000, max(2000, 8.0 / per_frame)))  # a call of about 8 s
    timer = threading.Timer(0.5, _thread.interrupt_main)
    start = time.perf_counter()
    timer.start()
    with pytest.raises(KeyboardInterrupt):
        fillgs.observe(m, cams, frames=frames, mode="raytraced")
        timer.join()
        pytest.fail(f"observe of {frames} frames ended in {time.perf_counter() - start:.1f} s without the interrupt")
    stopped = time.perf_counter() - start
    timer.join()
    assert stopped < 0.5 + 1.0, (stopped, frames, per_frame)
