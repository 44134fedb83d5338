"""The package as users of Python packages expect it: __version__ as `fillgs --version` says,
signatures inspect can read, stubs whose keywords and defaults are the functions' own (read
from the stub file with ast, compared with the runtime signatures), errors that name the
Python keyword where the command line names a flag, and progress=True saying when tqdm is
missing. The install into a fresh venv is CTest's python_install (tests/CMakeLists.txt).

Run by CTest's python_module with test_module.py (same environment)."""
import ast
import inspect
import os
import subprocess
import sys
import warnings

import pytest

import fillgs

CLI = os.environ["FILLGS_BIN"]
FIXTURES = os.environ["FILLGS_MODEL_FIXTURES"]
STUBS = os.path.join(os.path.dirname(fillgs.__file__), "__init__.pyi")


def test_version_is_the_command_lines():
    first = subprocess.run([CLI, "--version"], capture_output=True, text=True, check=True).stdout.splitlines()[0]
    assert first == f"fillgs {fillgs.__version__}"


def stub_functions():
    tree = ast.parse(open(STUBS).read())
    out = {n.name: n for n in tree.body if isinstance(n, ast.FunctionDef)}
    for c in (n for n in tree.body if isinstance(n, ast.ClassDef)):
        for f in (n for n in c.body if isinstance(n, ast.FunctionDef) and n.name == "__init__"):
            out[c.name] = f
    return out


def test_every_function_has_a_signature_and_a_stub_that_agree():
    stubs = stub_functions()
    public = [n for n in dir(fillgs) if not n.startswith("_") and (callable(getattr(fillgs, n)) and n[0].islower() or n == "Cameras")]
    assert public, dir(fillgs)
    for name in public:
        sig = inspect.signature(getattr(fillgs, name))
        assert name in stubs, f"{name} has no stub"
        args = stubs[name].args
        names = [a.arg for a in args.args if a.arg != "self"] + ([args.kwarg.arg] if args.kwarg else [])
        assert names == list(sig.parameters), (name, names, list(sig.parameters))
        defaults = [ast.literal_eval(d) for d in args.defaults]
        runtime = [p.default for p in sig.parameters.values() if p.default is not inspect.Parameter.empty]
        assert defaults == runtime, (name, defaults, runtime)


def test_errors_name_the_keyword_not_the_flag():
    with pytest.raises(fillgs.Error) as e:
        fillgs.load_model(os.path.join(FIXTURES, "4dgs"))
    assert "give frames=F and time_range=T0:T1" in str(e.value) and "--model-frames" not in str(e.value)
    r = subprocess.run([CLI, "info", os.path.join(FIXTURES, "4dgs")], capture_output=True, text=True)
    assert "give --model-frames F and --model-time-range T0:T1" in r.stderr  # the same line, in the command line's words


def test_progress_true_without_tqdm_says_so(tmp_path):
    """A fresh interpreter in which tqdm cannot be imported (a module of that name that fails)."""
    (tmp_path / "tqdm.py").write_text("raise ImportError('no tqdm here')\n")
    code = ("import warnings, fillgs, numpy as np\n"
            "m = fillgs.model_from_arrays(dict(means=np.zeros((1, 3)), log_scales=np.full((1, 3), -2.0), quaternions=[[1, 0, 0, 0]], opacity_logits=[0.0]))\n"
            "c = fillgs.Cameras(np.array([[[100.0, 0, 32], [0, 100, 24], [0, 0, 1]]]), np.eye(4)[None], 64, 48)\n"
            "with warnings.catch_warnings(record=True) as w:\n"
            "    warnings.simplefilter('always')\n"
            "    fillgs.observe(m, c, frames=2, progress=True)\n"
            "print([str(x.message) for x in w])\n")
    env = dict(os.environ, PYTHONPATH=str(tmp_path) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
    assert r.returncode == 0, r.stderr
    assert "progress=True: tqdm is not installed, so no progress bar is shown" in r.stdout


@pytest.mark.parametrize("name, frames, time_last", [("ed3dgs", 0, 11 / 12), ("4dgaussians", 10, 0.9), ("deformable3dgs", 9, 1.0)])
def test_model_and_normalised_time(name, frames, time_last):
    """The codes' own time of frame f (E-D3DGS f / total_num_frames, 4DGaussians f / F,
    Deformable 3D Gaussians f / (F - 1): the fixtures' generator, tests/make_model_fixtures.py)
    and back."""
    m = fillgs.load_model(os.path.join(FIXTURES, name), frames=frames)
    assert m.model_time(0.0) == pytest.approx(0.0) and m.model_time(1.0) == pytest.approx(time_last, rel=1e-12)
    for t in (0.0, 0.37, 1.0):
        assert m.normalised_time(m.model_time(t)) == pytest.approx(t, abs=1e-12)
    with pytest.raises(fillgs.Error, match="lies outside the times the model covers"):
        m.normalised_time(time_last + 0.5)
    plain = fillgs.model_from_arrays(dict(means=[[0.0, 0, 5]], log_scales=[[-2.0, -2, -2]], quaternions=[[1.0, 0, 0, 0]], opacity_logits=[0.0]))
    assert plain.model_time(0.25) == 0.25 and plain.normalised_time(0.25) == 0.25


def test_cameras_from_3dgs_equal_the_cameras_json_3dgs_writes(tmp_path):
    """Cameras as the 3DGS family holds them (R = world-to-camera rotation transposed, T, FoV) against
    the same cameras written as 3DGS's camera_to_JSON writes cameras.json (numpy here), read by fillgs."""
    import json
    import math

    import numpy as np

    rng = np.random.default_rng(3)
    C, W, H = 4, 64, 48
    Rs, Ts, fovx, fovy, entries = [], [], [], [], []
    for i in range(C):
        q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        w2c = q * np.sign(np.linalg.det(q))  # a rotation
        R, T = w2c.T, rng.normal(size=3)      # what scene/cameras.py keeps
        fx_, fy_ = 0.9 + 0.1 * i, 0.7 + 0.05 * i
        Rt = np.eye(4)
        Rt[:3, :3], Rt[:3, 3] = R.T, T        # getWorld2View2
        c2w = np.linalg.inv(Rt)
        entries.append({"id": i, "img_name": f"v{i}", "width": W, "height": H, "position": c2w[:3, 3].tolist(), "rotation": c2w[:3, :3].tolist(),
                        "fy": H / (2 * math.tan(fy_ / 2)), "fx": W / (2 * math.tan(fx_ / 2))})  # fov2focal
        Rs.append(R), Ts.append(T), fovx.append(fx_), fovy.append(fy_)
    path = tmp_path / "cameras.json"
    path.write_text(json.dumps(entries))
    want = fillgs.read_cameras(str(path)).arrays()
    got = fillgs.cameras_from_3dgs(np.array(Rs), np.array(Ts), fovx, fovy, W, H, names=[f"v{i}" for i in range(C)]).arrays()
    assert np.allclose(got["K"], want["K"], atol=1e-4) and np.allclose(got["world_to_camera"], want["world_to_camera"], atol=1e-5)
    with pytest.raises(fillgs.Error, match="fov: element 0 has a field of view of 4 radians"):
        fillgs.cameras_from_3dgs(np.array(Rs[:1]), np.array(Ts[:1]), 4.0, 1.0, W, H)
    # And back: the cameras fillgs read from that cameras.json, as the codes hold them.
    back = fillgs.read_cameras(str(path)).to_3dgs()
    np.testing.assert_allclose(back["R"], np.array(Rs), atol=1e-6)
    np.testing.assert_allclose(back["T"], np.array(Ts), atol=1e-6)
    np.testing.assert_allclose(back["fov_x"], fovx, atol=1e-6)
    np.testing.assert_allclose(back["fov_y"], fovy, atol=1e-6)
    assert back["width"].tolist() == [W] * C and back["height"].tolist() == [H] * C
    K = want["K"].copy()
    K[1, 0, 2] += 3.0  # camera 1's principal point 3 px right of the centre: the codes have none of their own
    with pytest.raises(fillgs.Error, match=r"element 1 \(v1\) has its principal point at \(35, 24\)"):
        fillgs.Cameras(K, want["world_to_camera"], W, H, names=[f"v{i}" for i in range(C)]).to_3dgs()
