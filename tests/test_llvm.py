"""libLLVM selection (integrators/llvm.py): parsing, choice, and the clear error."""
import sys
import types

import pytest

from integrators import llvm


@pytest.mark.parametrize("path,version", [
    ("/usr/lib/x86_64-linux-gnu/libLLVM-19.so", 19),
    ("/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1", 19),
    ("/usr/lib/llvm-17/lib/libLLVM.so", 17),
    ("/usr/lib/x86_64-linux-gnu/libLLVM-15.so.1", 15),
    ("/usr/lib64/libLLVM18.so", 18),
    ("/usr/lib/libfoo.so", None),
])
def test_library_version(path, version):
    assert llvm.library_version(path) == version


def test_find_library_picks_newest_suitable(monkeypatch):
    monkeypatch.setattr(llvm, "candidates", lambda: [(19, "/a/libLLVM-19.so"),
                                                     (15, "/a/libLLVM-15.so")])
    assert llvm.find_library() == "/a/libLLVM-19.so"
    monkeypatch.setattr(llvm, "candidates", lambda: [(15, "/a/libLLVM-15.so"),
                                                     (14, "/a/libLLVM-14.so")])
    assert llvm.find_library() is None


def test_configure_explains_a_bad_llvm_already_loaded(monkeypatch):
    fake = types.SimpleNamespace(detail=types.SimpleNamespace(llvm_version=lambda: (15, 0, 6)))
    monkeypatch.setitem(sys.modules, "drjit", fake)
    with pytest.raises(llvm.LLVMError, match=r"libLLVM 15.*>= 17.*apt-get install libllvm19"):
        llvm.configure()


def test_configure_sets_the_variable_before_drjit(monkeypatch):
    monkeypatch.delitem(sys.modules, "drjit")
    monkeypatch.delenv(llvm.ENV_VAR, raising=False)
    monkeypatch.setattr(llvm, "candidates", lambda: [(19, "/a/libLLVM-19.so")])
    assert llvm.configure() == "/a/libLLVM-19.so"
    import os
    assert os.environ[llvm.ENV_VAR] == "/a/libLLVM-19.so"


def test_ensure_without_llvm_and_without_root_says_what_to_install(monkeypatch, capsys):
    monkeypatch.delenv(llvm.ENV_VAR, raising=False)
    monkeypatch.setattr(llvm, "candidates", lambda: [(15, "/a/libLLVM-15.so")])
    monkeypatch.setattr(llvm.os, "geteuid", lambda: 1000)
    assert llvm.ensure() == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "libllvm19" in err[0] and ">= 17" in err[0]
