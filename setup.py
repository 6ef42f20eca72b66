"""Builds the `opl` Python module with CMake for `pip install .`.

The pattern of pybind11's cmake_example: a setuptools Extension with no
sources whose build_ext runs CMake (the module target only: no tools, tests or
benchmarks) for the Python that runs pip, and copies the module where the
wheel wants it. Needs what the CMake build needs (.ci/deps). Environment:
  CMAKE_ARGS        extra arguments for the CMake configure step
  CMAKE_BUILD_PARALLEL_LEVEL  jobs (default: every core)
docs/python.md.
"""
import os
import pathlib
import shutil
import subprocess
import sys

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

ROOT = pathlib.Path(__file__).resolve().parent


class CMakeExtension(Extension):
    def __init__(self, name):
        super().__init__(name, sources=[])


class CMakeBuild(build_ext):
    def build_extension(self, ext):
        target = pathlib.Path(self.get_ext_fullpath(ext.name)).resolve()
        build_dir = pathlib.Path(self.build_temp).resolve() / "cmake"
        build_dir.mkdir(parents=True, exist_ok=True)
        configure = [
            "cmake", "-S", str(ROOT), "-B", str(build_dir),
            "-DCMAKE_BUILD_TYPE=Release",
            f"-DPython3_EXECUTABLE={sys.executable}",
            "-DOPL_BUILD_PYTHON=ON", "-DOPL_BUILD_TESTS=OFF", "-DOPL_BUILD_BENCHMARKS=OFF",
            "-DOPL_BUILD_APPS=OFF", "-DOPL_BUILD_SEQUENCER=OFF",
        ]
        if shutil.which("ninja"):
            configure += ["-G", "Ninja"]
        configure += [a for a in os.environ.get("CMAKE_ARGS", "").split() if a]
        env = dict(os.environ)
        env.setdefault("CCACHE_BASEDIR", str(ROOT))  # as .ci/build: reuse the cache of other builds
        env.setdefault("CCACHE_NOHASHDIR", "1")
        jobs = env.get("CMAKE_BUILD_PARALLEL_LEVEL", str(os.cpu_count() or 1))
        subprocess.run(configure, check=True, env=env)
        subprocess.run(["cmake", "--build", str(build_dir), "--target", "opl_python", "-j", jobs],
                       check=True, env=env)
        built = list((build_dir / "python").glob("opl*.so"))
        if len(built) != 1:
            raise RuntimeError(f"setup.py: expected one opl*.so in {build_dir / 'python'}, found {built}")
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(built[0], target)


setup(
    ext_modules=[CMakeExtension("opl")],
    cmdclass={"build_ext": CMakeBuild},
    # Not build/: that is where .ci/build puts the CMake tree.
    options={"build": {"build_base": "build-pip"}},
    zip_safe=False,
)
