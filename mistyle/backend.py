"""Mitsuba variant selection and the Dr.Jit LLVM backend check.

This module owns one convention: which Mitsuba variant runs. ``use_variant`` is the only caller of
``mi.set_variant`` in mistyle; everything else asks it for the variant that matches a torch device.

Dr.Jit 1.5 compiles its CPU kernels with the system's libLLVM. With LLVM 14-16 every kernel aborts
the process with ``LLVM ERROR: Cannot select: fminimum``; with no libLLVM at all the backend stays
inactive. Both are caught here, before the first kernel runs, and turned into a ``BackendError``
that names the fix.
"""

from __future__ import annotations

import contextlib
import functools
import os
import re
import subprocess
import sys

from .conventions import DEVICES

MIN_LLVM_MAJOR = 17
VARIANTS = ("llvm_ad_rgb", "cuda_ad_rgb")

_FIX = (
    "Fix: install a recent libLLVM (Debian/Ubuntu: `apt-get install libllvm19`, which "
    "`make test`/`make demo` do for you), or point Dr.Jit at one with "
    "DRJIT_LIBLLVM_PATH=/path/to/libLLVM.so.19.1"
)


class BackendError(RuntimeError):
    """The requested Mitsuba/Dr.Jit backend cannot run on this machine."""


def variant_for(device: str = "cpu") -> str:
    """Mitsuba variant for a torch device: ``llvm_ad_rgb`` on CPU, ``cuda_ad_rgb`` on CUDA."""
    kind = str(device).split(":")[0]
    if kind == "cpu":
        return "llvm_ad_rgb"
    if kind == "cuda":
        return "cuda_ad_rgb"
    raise ValueError(f"Unsupported torch device {device!r}: use 'cpu' or 'cuda[:N]'.")


def use_variant(device: str = "cpu"):
    """Activate (once) and return the Mitsuba module in the variant matching ``device``."""
    name = variant_for(device)
    if name.startswith("llvm"):
        check_llvm_backend()
    else:
        check_cuda_backend()
    import mitsuba as mi

    if mi.variant() != name:
        if name not in mi.variants():
            raise BackendError(f"Mitsuba was built without the {name!r} variant.")
        mi.set_variant(name)
    return mi


def active_variant():
    """The Mitsuba module in the variant already chosen by ``use_variant``, else in the one of the
    ``MISTYLE_DEVICE`` environment variable (``cpu``, the default, or ``cuda``), so a machine without
    libLLVM can run code that calls this first (``MISTYLE_DEVICE=cuda``).

    For code that computes with Mitsuba; scene-dictionary builders use ``require_variant``.
    """
    import mitsuba as mi

    if mi.variant() in VARIANTS:
        return mi
    device = os.environ.get("MISTYLE_DEVICE", "cpu")
    if device not in DEVICES:
        raise ValueError(f"MISTYLE_DEVICE={device!r}: set it to {' or '.join(map(repr, DEVICES))}, or unset it (cpu).")
    return use_variant(device)


def require_variant():
    """The Mitsuba module in the variant ``use_variant`` chose; never chooses one itself.

    Scene dictionaries hold variant-specific objects (transforms, grids), so their builders need a
    variant, but they must not switch it behind the caller's back.
    """
    import mitsuba as mi

    if mi.variant() not in VARIANTS:
        raise BackendError(
            "No mistyle Mitsuba variant is active; call mistyle.backend.use_variant('cpu') "
            "(or 'cuda') before building scenes."
        )
    return mi


KERNEL_INPUT_ALIGNMENT = 64
"""Bytes: where NumPy arrays handed to Dr.Jit as per-lane inputs start (``lanes``)."""


def lanes(kind, values):
    """``kind(values)`` for a Dr.Jit array type of the active variant (``mi.Float``, ``mi.UInt32``,
    ``mi.Int32``), from a copy of ``values`` that starts on a ``KERNEL_INPUT_ALIGNMENT`` boundary.

    The LLVM backend reads a NumPy array where it lies and compiles each kernel that loads it for
    that address's alignment (``align 64`` or ``align 1``). Arrays that land wherever the allocator
    puts them make a new kernel variant on frames whose buffers happened to land elsewhere, so a
    sequence would keep compiling; aligned, each kernel compiles once per run."""
    import drjit as dr
    import numpy as np

    dtype = np.dtype(
        {dr.VarType.Float32: np.float32, dr.VarType.UInt32: np.uint32, dr.VarType.Int32: np.int32}[dr.type_v(kind)]
    )
    flat = np.asarray(values).ravel()
    padded = np.empty(flat.size + KERNEL_INPUT_ALIGNMENT // dtype.itemsize, dtype)
    start = (-padded.ctypes.data % KERNEL_INPUT_ALIGNMENT) // dtype.itemsize
    aligned = padded[start : start + flat.size]
    aligned[...] = flat
    return kind(aligned)


@contextlib.contextmanager
def ordered_sums():
    """Within it, Dr.Jit's CPU backend runs kernels on one thread, so that a scatter-add (an adjoint pass
    gathering a grid's gradient from every ray) sums in one fixed order. On several threads each run
    adds in the order the threads happen to take the work, and a look fitted twice on the same frame
    differed by up to 2.5e-4 in albedo; summed in order, a fit is the same bit for bit run after run and
    in any thread (the live preview fits in its worker's). Adjoint passes of the fast layer are small:
    the look's fit took the same time either way on this project's 2-core CPU. CUDA's atomics are
    unordered whatever this does."""
    import drjit as dr

    previous = dr.thread_count()
    dr.sync_thread()  # the pool must be idle while it is resized
    dr.set_thread_count(1)
    try:
        yield
    finally:
        dr.sync_thread()
        dr.set_thread_count(previous)


def _loaded_llvm_path() -> str | None:
    """Path of the libLLVM mapped into this process, if any (Linux only)."""
    try:
        with open("/proc/self/maps") as maps:
            for line in maps:
                if "libLLVM" in line:
                    return line.split()[-1]
    except OSError:
        pass
    return None


def llvm_major_from_path(path: str) -> int | None:
    """LLVM major version encoded in a library file name, e.g. ``libLLVM.so.19.1`` -> 19."""
    match = re.search(r"libLLVM(?:-(\d+)|\.so\.(\d+))", os.path.basename(path))
    if not match:
        return None
    return int(match.group(1) or match.group(2))


@functools.lru_cache(maxsize=1)
def check_llvm_backend() -> str:
    """Make sure Dr.Jit's LLVM backend is active with LLVM >= 17; return the library's path.

    Raises:
        BackendError: naming the problem and the fix, instead of an LLVM abort later on.
    """
    import drjit as dr

    if not dr.has_backend(dr.JitBackend.LLVM):
        raise BackendError(f"Dr.Jit's LLVM backend is inactive: no usable libLLVM was found. {_FIX}.")
    path = _loaded_llvm_path()
    major = llvm_major_from_path(path) if path else None
    if major is None:
        # Unknown naming (or no /proc): run one kernel in a child process, where an abort is harmless.
        if not _llvm_kernel_runs_in_subprocess():
            raise BackendError(
                f"Dr.Jit's LLVM backend loaded {path or 'a libLLVM'} but cannot compile kernels "
                f"(likely LLVM < {MIN_LLVM_MAJOR}). {_FIX}."
            )
        return path or "unknown libLLVM"
    if major < MIN_LLVM_MAJOR:
        raise BackendError(
            f"Dr.Jit's LLVM backend loaded {path} (LLVM {major}); Dr.Jit 1.5 needs LLVM >= "
            f"{MIN_LLVM_MAJOR} (LLVM 14-16 abort with 'Cannot select: fminimum'). {_FIX}."
        )
    return path


def _llvm_kernel_runs_in_subprocess() -> bool:
    probe = (
        "import drjit as dr\n"
        "from drjit.llvm import Float\n"
        "x = dr.arange(Float, 8)\n"
        "assert dr.sum(dr.minimum(x, 3.0))[0] == 18.0  # 0+1+2+3*5\n"
    )
    result = subprocess.run([sys.executable, "-c", probe], capture_output=True, timeout=300)
    return result.returncode == 0


def check_cuda_backend(cpu_option: str = "--device cpu") -> None:
    """``BackendError`` unless Dr.Jit's CUDA backend is active; the message says to use ``cpu_option``
    (the command line's ``--device cpu``, the API's ``device="cpu"``) instead."""
    import drjit as dr

    if not dr.has_backend(dr.JitBackend.CUDA):
        raise BackendError(
            f"Dr.Jit's CUDA backend is inactive (no NVIDIA driver/GPU visible). Run with "
            f"{cpu_option} to use the llvm_ad_rgb variant instead."
        )


def check_device(device, cpu_option: str = "--device cpu") -> str:
    """``device`` (``conventions.DEVICES``) if this machine can run mistyle on it, before any work.

    ``ValueError`` for another device; for ``cuda``, ``BackendError`` when Dr.Jit (the path tracer) or
    torch (the network) sees no GPU, naming ``cpu_option`` as the way around."""
    if device not in DEVICES:
        raise ValueError(f"device must be one of {', '.join(map(repr, DEVICES))}, got {device!r}.")
    if device == "cuda":
        check_cuda_backend(cpu_option)
        import torch

        if not torch.cuda.is_available():
            raise BackendError(
                f"torch {torch.__version__} sees no CUDA GPU (a CPU-only build, or no NVIDIA driver). "
                f"Run with {cpu_option}, or install a CUDA build of torch."
            )
    return device
