"""Generated C, compiled once per machine and kept in a disk cache shared by every process.

The source is generated in memory (``CodeGenerator.dump``), compiled in a private temporary
directory and moved into the cache atomically (write to a temporary name in the cache, then
``os.replace``), so concurrent processes (Dask workers starting cold, a process pool) never read
each other's half-written files, and nothing is written to the current working directory (a
read-only one is fine). The cache is ``$CASADRONE_CACHE`` or ``~/.cache/casadrone``; a library's
name carries the hash of its source, compiler flags and CasADi version. The temporary directory
is removed on every exit Python sees (an error, Ctrl-C); a staged file that a killed process
(SIGKILL) left in the cache is removed by a later compile once it is an hour old.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import subprocess
import tempfile
import threading
import time
from pathlib import Path

import casadi as ca
import numpy as np

DEFAULT_FLAGS: tuple[str, ...] = ("-O2",)


def cache_dir() -> Path:
    """Where compiled closed loops are kept between processes."""
    root = os.environ.get("CASADRONE_CACHE") or Path.home() / ".cache" / "casadrone"
    path = Path(root)
    path.mkdir(parents=True, exist_ok=True)
    return path


def casadi_source(fun: ca.Function, extra: str = "") -> str:
    """C source of ``fun`` (CasADi's code generator, in memory), with ``extra`` C appended."""
    gen = ca.CodeGenerator(f"{fun.name()}.c", {"with_header": False})
    gen.add(fun)
    return gen.dump() + extra


def compile_source(name: str, src: str, flags: tuple[str, ...] = DEFAULT_FLAGS) -> Path:
    """The shared library of C source ``src``: from the cache, or compiled now and cached.

    Raises OSError or CalledProcessError when there is no working C compiler (``$CC``, else gcc).
    """
    version = ca.__version__  # type: ignore[attr-defined]  # absent from the stubs
    digest = hashlib.sha256("\0".join([src, *flags, version]).encode()).hexdigest()[:16]
    cache = cache_dir()
    target = cache / f"{name}_{digest}.so"
    if target.exists():
        return target
    _remove_stale(cache)
    with tempfile.TemporaryDirectory(prefix="casadrone-cc-") as tmp:  # removed on any exit
        c_file, so_file = Path(tmp) / f"{name}.c", Path(tmp) / f"{name}.so"
        c_file.write_text(src)
        cc = os.environ.get("CC", "gcc")
        subprocess.run([cc, *flags, "-shared", "-fPIC", str(c_file), "-o", str(so_file), "-lm"],
                       check=True, capture_output=True)
        fd, staged = tempfile.mkstemp(prefix=f".{name}_", suffix=".tmp", dir=cache)
        try:
            with os.fdopen(fd, "wb") as out:
                out.write(so_file.read_bytes())
            os.chmod(staged, 0o755)
            os.replace(staged, target)  # atomic: readers see the old name absent or complete
        finally:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(staged)
    return target


def _remove_stale(cache: Path, age_s: float = 3600.0) -> None:
    """Remove staged files that a process killed mid-install (SIGKILL: no cleanup runs) left in
    the cache more than ``age_s`` ago; a compile in progress elsewhere is younger."""
    now = time.time()
    for staged in cache.glob(".*.tmp"):
        with contextlib.suppress(OSError):
            if now - staged.stat().st_mtime > age_s:
                staged.unlink()


def compile_function(fun: ca.Function, flags: tuple[str, ...] = DEFAULT_FLAGS) -> ca.Function:
    """Generate C for ``fun``, compile it once (cached on disk by source hash) and load it."""
    return ca.external(fun.name(), str(compile_source(fun.name(), casadi_source(fun), flags)))


class ZeroCopyCall:
    """Calls a CasADi Function through numpy arrays bound once to its memory
    (``Function.buffer``): no DM conversion, a few µs per call instead of tens.

    Each thread gets its own buffers. Output ``i`` is a (columns × rows) array, i.e. one row per
    column of a matrix output (``.T`` gives the matrix); outputs must be dense, and they are
    overwritten by the next call in the same thread: copy what you keep.
    """

    def __init__(self, fun: ca.Function):
        for i in range(fun.n_out()):
            if not fun.sparsity_out(i).is_dense():
                raise ValueError(f"{fun.name()}: output {fun.name_out(i)} is sparse; densify it")
        self.fun = fun
        self._local = threading.local()

    def _bound(self):
        bound = getattr(self._local, "bound", None)
        if bound is None:
            fun = self.fun
            buf, trigger = fun.buffer()
            args = [np.zeros(fun.nnz_in(i)) for i in range(fun.n_in())]
            outs = [np.zeros((fun.size2_out(i), fun.size1_out(i))) for i in range(fun.n_out())]
            for i, a in enumerate(args):
                buf.set_arg(i, memoryview(a))
            for i, o in enumerate(outs):
                buf.set_res(i, memoryview(o.reshape(-1)))
            bound = self._local.bound = (buf, trigger, args, outs)
        return bound

    def __call__(self, *inputs) -> list[np.ndarray]:
        """Evaluate on ``inputs`` (anything numpy turns into the input's values)."""
        _, trigger, args, outs = self._bound()
        for dst, src in zip(args, inputs, strict=True):
            dst[:] = np.asarray(src, float).ravel(order="F")
        trigger()
        return outs

    def stats(self) -> dict:
        """The Function's statistics of this thread's last call (solvers: iterations, status)."""
        return self._bound()[0].stats()
