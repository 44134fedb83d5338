"""Builds the Python package fillgs with CMake, for the Python that runs pip:

    python -m pip install --no-build-isolation .

The extension fillgs._fillgs is CMake's target fillgs_python (CMakeLists.txt), configured
with Python3_EXECUTABLE set to this interpreter, in build/pip/cmake-<its ABI tag>; the package's
Python files come from src/python/fillgs. FILLGS_BUILD_DIR names a build tree to use instead
(configured already, e.g. by scripts/build.sh --tests: its module must be this interpreter's
ABI, or the install stops saying so). Nothing is downloaded."""
import os
import re
import shutil
import subprocess
import sys
import sysconfig

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

ROOT = os.path.dirname(os.path.abspath(__file__))
os.makedirs(os.path.join(ROOT, "build", "pip"), exist_ok=True)  # setuptools' own build and egg-info folder


def version():
    """The project's version, as CMakeLists.txt's project() line and `fillgs --version` say."""
    with open(os.path.join(ROOT, "CMakeLists.txt")) as f:
        return re.search(r"project\(fillgs VERSION ([0-9.]+)", f.read()).group(1)


class CMakeBuild(build_ext):
    def build_extension(self, ext):
        suffix = sysconfig.get_config_var("EXT_SUFFIX")
        given = os.environ.get("FILLGS_BUILD_DIR")
        build = os.path.abspath(given) if given else os.path.join(ROOT, "build", "pip", "cmake-" + sysconfig.get_config_var("SOABI"))
        if not os.path.exists(os.path.join(build, "CMakeCache.txt")):
            if given:
                sys.exit(f"fillgs: FILLGS_BUILD_DIR={given} is no configured build tree (no CMakeCache.txt)")
            generator = ["-G", "Ninja"] if shutil.which("ninja") else []
            subprocess.check_call(["cmake", "-S", ROOT, "-B", build, *generator, "-DCMAKE_BUILD_TYPE=Release", f"-DPython3_EXECUTABLE={sys.executable}",
                                   "-DBUILD_TESTING=OFF", "-DFILLGS_MPI=OFF"])
        subprocess.check_call(["cmake", "--build", build, "--target", "fillgs_python", "-j", str(os.cpu_count() or 2)])
        built = os.path.join(build, "python", "fillgs", "_fillgs" + suffix)
        if not os.path.exists(built):
            found = [n for n in os.listdir(os.path.join(build, "python", "fillgs")) if n.startswith("_fillgs")]
            sys.exit(f"fillgs: {build} built {', '.join(found) or 'no module'}, not _fillgs{suffix} for {sys.executable} "
                     f"(Python {sys.version.split()[0]}); configure it for this Python, or leave FILLGS_BUILD_DIR unset")
        target = self.get_ext_fullpath(ext.name)
        os.makedirs(os.path.dirname(target), exist_ok=True)
        shutil.copyfile(built, target)


setup(
    version=version(),
    packages=["fillgs"],
    package_dir={"fillgs": "src/python/fillgs"},
    package_data={"fillgs": ["__init__.pyi", "py.typed"]},
    ext_modules=[Extension("fillgs._fillgs", sources=[])],
    cmdclass={"build_ext": CMakeBuild},
    options={"build": {"build_base": os.path.join("build", "pip")}, "egg_info": {"egg_base": os.path.join("build", "pip")}},
    zip_safe=False,
)
