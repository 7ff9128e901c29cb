"""The compiled kernels (Cython 3): everything else is in pyproject.toml.

Each ``.pyx`` next to the module that uses it is one extension.  Compiled without
contracting ``a * b + c`` into fused multiply-adds, so a kernel's arithmetic is the
same on every processor (x86-64 and ARM give the same bytes).
"""

from pathlib import Path

from Cython.Build import cythonize
from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

HERE = Path(__file__).parent
KERNELS = sorted(p.relative_to(HERE).as_posix() for p in (HERE / "deformesh_cli").rglob("*.pyx"))


class BuildExt(build_ext):
    def build_extensions(self):
        if self.compiler.compiler_type == "msvc":
            flags = ["/O2", "/fp:precise"]
        else:
            flags = ["-O2", "-ffp-contract=off"]
        for ext in self.extensions:
            ext.extra_compile_args = flags
        super().build_extensions()


setup(
    ext_modules=cythonize(
        [Extension(k[:-4].replace("/", "."), [k]) for k in KERNELS],
        compiler_directives={"language_level": 3},
        build_dir="build/cython",  # (the generated C stays out of the package)
    ),
    cmdclass={"build_ext": BuildExt},
)
