#!/usr/bin/env bash
# `pip install --no-build-isolation .` into a fresh venv (with the system's site packages, as a
# user's environment with its own torch would be), then the package imported from there, away
# from the source and build trees: __version__, the stubs, py.typed, signatures, one call.
# FILLGS_BUILD_DIR is the tree CTest runs in, so pip compiles nothing new; a fresh install
# configures and builds its own tree (setup.py).
#   tests/python_install.sh OUT SOURCE BUILD PYTHON
set -euo pipefail
out=$1 src=$2 build=$3 python=$4
rm -rf "$out" && mkdir -p "$out"
"$python" -m venv --system-site-packages "$out/venv"
(cd "$src" && FILLGS_BUILD_DIR=$build "$out/venv/bin/python" -m pip install --no-build-isolation --no-index --no-deps -q .)
cd "$out"
PYTHONPATH= "$out/venv/bin/python" - <<'PY'
import inspect, os, sys
import numpy as np
import fillgs
where = os.path.dirname(fillgs.__file__)
assert where.startswith(sys.prefix), (where, sys.prefix)  # the venv's, not the build tree's
for f in ("__init__.pyi", "py.typed"):
    assert os.path.exists(os.path.join(where, f)), f
assert fillgs.__version__.count(".") == 2, fillgs.__version__
assert list(inspect.signature(fillgs.observe).parameters)[:3] == ["model", "cameras", "frames"]
m = fillgs.model_from_arrays(dict(means=np.array([[0.0, 0, 5]]), log_scales=np.full((1, 3), -2.0), quaternions=[[1, 0, 0, 0]], opacity_logits=[0.0]))
c = fillgs.Cameras(np.array([[[100.0, 0, 32], [0, 100, 24], [0, 0, 1]]]), np.eye(4)[None], 64, 48)
assert fillgs.observe(m, c, frames=2)["counts"].tolist() == [[1], [1]]
print(f"python_install: fillgs {fillgs.__version__} installed in {sys.prefix} and imported from there")
PY
"$out/venv/bin/python" -m pip uninstall -y -q fillgs
