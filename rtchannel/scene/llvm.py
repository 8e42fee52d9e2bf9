"""Find a libLLVM that Dr.Jit's CPU backend can use, before mitsuba is imported.

Dr.Jit loads libLLVM at run time. With LLVM 15 (Debian 12's default) it aborts the whole process
("LLVM ERROR: Cannot select ... fmaximum"), so we never let it pick one on its own: we look for
LLVM >= 16, point ``DRJIT_LIBLLVM_PATH`` at it, and otherwise raise one clear error.
"""
from __future__ import annotations

import glob
import os
import re

from processing.errors import InputError

MIN_LLVM_MAJOR = 16
INSTALL_HINT = "install LLVM >= 16, e.g. 'apt-get install -y libllvm19' on Debian 12"

_SEARCH_GLOBS = (
    "/usr/lib/x86_64-linux-gnu/libLLVM*.so*",
    "/usr/lib/aarch64-linux-gnu/libLLVM*.so*",
    "/usr/lib/llvm-*/lib/libLLVM*.so*",
    "/usr/lib64/libLLVM*.so*",
    "/usr/local/lib/libLLVM*.so*",
    "/opt/homebrew/opt/llvm/lib/libLLVM*.dylib",
    "/usr/local/opt/llvm/lib/libLLVM*.dylib",
)


class LLVMNotFoundError(InputError):
    """No usable libLLVM is installed; the message says what to install (a problem of the environment, not a
    bug: the CLI prints it as one line with exit status 2)."""


def _major(path: str) -> int | None:
    name = os.path.basename(path)
    m = re.search(r"libLLVM[-.]?(\d+)", name) or re.search(r"llvm-(\d+)", path)
    if m:
        return int(m.group(1))
    m = re.search(r"\.so\.(\d+)", name)
    return int(m.group(1)) if m else None


def find_libllvm() -> str | None:
    """Path of the newest installed libLLVM with major version >= 16, or None."""
    found: list[tuple[int, str]] = []
    for pattern in _SEARCH_GLOBS:
        for path in glob.glob(pattern):
            major = _major(path)
            if major is not None and major >= MIN_LLVM_MAJOR and os.path.isfile(path):
                found.append((major, path))
    return max(found)[1] if found else None


def ensure_libllvm() -> str:
    """Set ``DRJIT_LIBLLVM_PATH`` to a usable libLLVM and return it.

    A path the user already set is kept if it names LLVM >= 16 (or an unversioned file we cannot
    judge). Raises `LLVMNotFoundError` with a one-line install hint when none is usable.
    """
    user = os.environ.get("DRJIT_LIBLLVM_PATH")
    if user:
        major = _major(user)
        if os.path.isfile(user) and (major is None or major >= MIN_LLVM_MAJOR):
            return user
    path = find_libllvm()
    if path is None:
        raise LLVMNotFoundError(f"no usable libLLVM (>= {MIN_LLVM_MAJOR}) found for Dr.Jit: {INSTALL_HINT}")
    os.environ["DRJIT_LIBLLVM_PATH"] = path
    return path


def import_mitsuba(variant: str = "llvm_ad_mono_polarized"):
    """Import mitsuba with a usable libLLVM and the given variant; returns the module."""
    ensure_libllvm()
    import mitsuba as mi

    if mi.variant() != variant:
        mi.set_variant(variant)
    return mi
