"""Variant selection and the libLLVM check: clear errors, never an LLVM abort."""

import glob
import os
import subprocess
import sys

import pytest

from mistyle.backend import (
    MIN_LLVM_MAJOR,
    check_llvm_backend,
    llvm_major_from_path,
    variant_for,
)


def test_variant_follows_the_torch_device():
    assert variant_for("cpu") == "llvm_ad_rgb"
    assert variant_for("cuda") == variant_for("cuda:1") == "cuda_ad_rgb"
    with pytest.raises(ValueError, match="Unsupported torch device"):
        variant_for("mps")


@pytest.mark.parametrize(
    "name,major",
    [
        ("libLLVM.so.19.1", 19),
        ("libLLVM-15.so.1", 15),
        ("libLLVM-14.0.6.so.1", 14),
        ("libLLVM-17.so", 17),
        ("libfoo.so", None),
    ],
)
def test_llvm_version_is_read_from_the_library_name(name, major):
    assert llvm_major_from_path(f"/usr/lib/{name}") == major


def test_this_machine_has_a_working_llvm_backend():
    path = check_llvm_backend()
    major = llvm_major_from_path(path)
    if major is not None:
        assert major >= MIN_LLVM_MAJOR
    # Whatever the library is called, a kernel with the operation old LLVMs cannot select must run.
    import drjit as dr
    from drjit.llvm import Float

    x = dr.arange(Float, 8)
    assert float(dr.sum(dr.minimum(x, 3.0))[0]) == 18.0  # 0 + 1 + 2 + 3 * 5


def run_check_with(libllvm: str) -> subprocess.CompletedProcess:
    code = (
        "from mistyle.backend import use_variant, BackendError\n"
        "try:\n    use_variant('cpu')\nexcept BackendError as e:\n    print('BackendError:', e)\n"
    )
    env = dict(os.environ, DRJIT_LIBLLVM_PATH=libllvm)
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=300)


def test_missing_libllvm_gives_a_clear_error():
    result = run_check_with("/nonexistent/libLLVM.so")
    assert result.returncode == 0, result.stderr
    assert "BackendError:" in result.stdout
    assert "libllvm19" in result.stdout and "DRJIT_LIBLLVM_PATH" in result.stdout


OLD_LLVMS = list({llvm_major_from_path(p): p for p in sorted(glob.glob("/usr/lib/*/libLLVM-1[456].so*"))}.values())


@pytest.mark.skipif(not OLD_LLVMS, reason="no LLVM 14-16 on this machine")
@pytest.mark.parametrize("library", OLD_LLVMS)
def test_old_libllvm_is_refused_before_any_kernel_runs(library):
    """Dr.Jit refuses LLVM 14 itself and loads 15/16, whose kernels would abort: both become errors."""
    result = run_check_with(library)
    assert result.returncode == 0, result.stderr[-2000:]
    assert "BackendError:" in result.stdout and "libllvm19" in result.stdout
    assert "LLVM ERROR" not in result.stderr


def test_the_subprocess_probe_for_unknown_library_names_passes_on_a_working_backend():
    from mistyle.backend import _llvm_kernel_runs_in_subprocess

    assert _llvm_kernel_runs_in_subprocess()
