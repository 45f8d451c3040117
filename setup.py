"""The compiled loops (``leolink._kernels``, C99); everything else is in pyproject.toml.

The extension is optional: where it cannot be built (no C compiler), leolink installs
without it and runs the numpy code everywhere (``leolink.compiled.enabled``). Its
floating point must not be re-associated or contracted (the loops repeat numpy's
operations bit for bit: ``src/leolink/_kernels.c``), so GCC and Clang get
``-ffp-contract=off``; ``-fno-math-errno`` lets ``sqrt`` be one instruction and
``-fno-trapping-math`` lets a loop compute both sides of a selection (the visibility
loop's arcsine) and vectorize: neither changes a value (no ``-fno-fast-math`` after them,
which would turn errno back on); ``-O3`` vectorizes.
"""

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

UNIX_FLAGS = ["-O3", "-ffp-contract=off", "-fno-math-errno", "-fno-trapping-math"]


class BuildExt(build_ext):
    def build_extensions(self):
        if self.compiler.compiler_type == "unix":  # GCC or Clang
            for ext in self.extensions:
                ext.extra_compile_args = [*ext.extra_compile_args, *UNIX_FLAGS]
                ext.libraries = [*ext.libraries, "m"]
        super().build_extensions()


setup(
    ext_modules=[Extension("leolink._kernels", ["src/leolink/_kernels.c"], optional=True)],
    cmdclass={"build_ext": BuildExt},
)
