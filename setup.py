"""Build of nsfem's optional compiled event core (nsfem/integrate/core/_*.pyx, Cython).

Everything else is in pyproject.toml. The extensions are optional: without Cython or a working C
compiler (``CC=false pip install .``) the package installs with its pure-Python event core, which
is the reference the compiled one is tested against (nsfem/integrate/core/__init__.py says which
runs). Compiled without -ffast-math and with floating-point contraction off, so each kernel rounds
as the Python reference does.
"""

from __future__ import annotations

import glob
import sys

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

#: no fused multiply-adds: a kernel must round each operation as the Python reference does. GCC's vectorizer
#: fuses complex products' multiply-adds (vfmaddsub) despite -ffp-contract=off where the target has FMA (CFLAGS
#: -march=haswell, x86-64-v3 or native; seen with GCC 12): it is off (no loss measured: the stop scene 0.099 s
#: either way; the band's explicit vector lanes are not the vectorizer's)
CFLAGS = ["-O2", "-ffp-contract=off", "-fno-fast-math", "-fno-tree-vectorize"]


def _note(text: str) -> None:
    print(f"nsfem: {text}; nsfem installs with its pure-Python event core", file=sys.stderr)


class OptionalBuildExt(build_ext):
    """build_ext that leaves an extension out, with a note, when it does not compile."""

    def run(self) -> None:
        try:
            super().run()
        except Exception as exc:  # no compiler at all (CC=false, no headers): keep the pure-Python core
            _note(f"the compiled event core was not built ({type(exc).__name__}: {exc})")

    def build_extension(self, ext) -> None:
        try:
            super().build_extension(ext)
        except Exception as exc:
            _note(f"{ext.name} was not compiled ({type(exc).__name__}: {exc})")


def extensions() -> list:
    sources = sorted(glob.glob("nsfem/integrate/core/_*.pyx"))
    try:
        from Cython.Build import cythonize
    except ImportError:
        if sources:
            _note("Cython is not installed, the compiled event core was not built")
        return []
    exts = [Extension(src[:-4].replace("/", "."), [src], extra_compile_args=CFLAGS, optional=True)
            for src in sources]
    directives = {"language_level": "3", "boundscheck": False, "wraparound": False, "cdivision": True,
                  "initializedcheck": False, "nonecheck": False}
    try:
        return cythonize(exts, compiler_directives=directives, quiet=True)
    except Exception as exc:
        _note(f"Cython could not translate the event core ({exc})")
        return []


setup(ext_modules=extensions(), cmdclass={"build_ext": OptionalBuildExt})
