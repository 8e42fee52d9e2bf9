import subprocess
import sys

import pytest

from rtchannel.scene import llvm


def test_finds_llvm_16_or_newer():
    path = llvm.find_libllvm()
    assert path is not None, "the set-up (make env) installs libllvm19"
    assert llvm._major(path) >= 16


def test_missing_llvm_is_one_clear_error(monkeypatch):
    monkeypatch.setattr(llvm, "_SEARCH_GLOBS", ())
    monkeypatch.delenv("DRJIT_LIBLLVM_PATH", raising=False)
    with pytest.raises(llvm.LLVMNotFoundError, match="libllvm19"):
        llvm.ensure_libllvm()


def test_llvm15_from_user_is_not_trusted(monkeypatch, tmp_path):
    fake = tmp_path / "libLLVM-15.so.1"
    fake.write_bytes(b"")
    monkeypatch.setenv("DRJIT_LIBLLVM_PATH", str(fake))
    assert llvm._major(llvm.ensure_libllvm()) >= 16


def test_mitsuba_imports_and_traces_without_abort():
    # In a subprocess: an LLVM abort would kill pytest itself.
    code = ("from rtchannel.scene.llvm import import_mitsuba; mi = import_mitsuba(); "
            "s = mi.load_dict({'type': 'scene', 's': {'type': 'sphere'}}); "
            "r = mi.Ray3f(mi.Point3f(0, 0, -5), mi.Vector3f(0, 0, 1)); "
            "print(float(s.ray_intersect(r).t[0]))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    assert float(out.stdout.strip().splitlines()[-1]) == pytest.approx(4.0, abs=1e-4)
