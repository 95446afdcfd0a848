"""Generated C, compiled once per machine and kept in a disk cache shared by every process.

The source is generated in memory (``CodeGenerator.dump``), compiled in a private temporary
directory and moved into the cache atomically (write to a temporary name in the cache, then
``os.replace``), so concurrent processes (Dask workers starting cold, a process pool) never read
each other's half-written files, and nothing is written to the current working directory (a
read-only one is fine). The cache is ``$CASADRONE_CACHE`` or ``~/.cache/casadrone``; a library's
name carries the hash of its source, compiler flags and CasADi version.

A compile ends with its command: the compiler runs in a process group of its own, killed whole
(driver, ``cc1``, assembler) on any exit Python sees (an error, Ctrl-C, and SIGTERM, which is
turned into a cleanup and then re-delivered when nothing else handles it). When casadrone dies by
SIGKILL, which it cannot see, the kernel signals the group's leader, a small shell that kills its
whole process group (:data:`GROUP_LEADER`): no ``cc1`` runs on alone. The temporary directory is
removed on every such exit; one that a SIGKILLed process left behind, and a staged file in the
cache, are removed by a later compile once an hour old. The first compile of a large source
says what it does on stderr (the limit lap's interval blocks take up to a few minutes). Without a C
compiler :class:`NoCompiler` says so; the closed-loop lap then runs on CasADi's virtual machine
(slower), the limit lap needs one.
"""

from __future__ import annotations

import contextlib
import errno
import functools
import hashlib
import inspect
import marshal
import os
import platform
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import casadi as ca
import numpy as np

from casadrone.progress import children_cpu_seconds, emit

DEFAULT_FLAGS: tuple[str, ...] = ("-O2",)


@functools.cache
def vector_flags() -> tuple[str, ...]:
    """``("-mavx2",)`` where this machine's CPU has AVX2 (read from Linux's /proc/cpuinfo on
    x86-64), else nothing: wide vector registers for the limit lap's interval blocks, whose
    straight-line SX code GCC (≥ 12 at -O2) packs into vector instructions. No FMA (``-mfma``
    would contract a*b + c and change the last bits), so the numbers stay those of the portable
    build to the last bit. The flags are part of a library's cache name: a machine without AVX2
    that shares the cache compiles and loads its own library, never this one."""
    if platform.machine().lower() not in ("x86_64", "amd64"):
        return ()
    try:
        text = Path("/proc/cpuinfo").read_text()
    except OSError:
        return ()
    return ("-mavx2",) if has_avx2(text) else ()


def has_avx2(cpuinfo: str) -> bool:
    """Whether Linux's /proc/cpuinfo text lists ``avx2`` among the first processor's flags."""
    for line in cpuinfo.splitlines():
        if line.startswith("flags"):
            return "avx2" in line.split(":", 1)[-1].split()
    return False


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


#: Sources at least this long (characters) are announced on stderr when compiled: the limit lap's
#: interval blocks (0.3-11 MB of C) take 5 s to a few minutes; the closed loop's few seconds stay
#: silent unless stderr is a terminal.
ANNOUNCE_CHARS = 500_000
TEMP_PREFIX = "casadrone-cc-"


class NoCompiler(OSError):
    """No working C compiler (``$CC``, else gcc) on this machine."""


def compile_source(name: str, src: str, flags: tuple[str, ...] = DEFAULT_FLAGS) -> Path:
    """The shared library of C source ``src``: from the cache, or compiled now and cached.

    Raises NoCompiler when ``$CC`` (else gcc) is not a program here, CalledProcessError when it
    fails on the source.
    """
    target = cache_dir() / f"{name}_{_digest(src, *flags)}.so"
    if not target.exists():
        _build(name, src, flags, target)
    return target


def _digest(*parts: str) -> str:
    version = ca.__version__  # type: ignore[attr-defined]  # absent from the stubs
    return hashlib.sha256("\0".join([*parts, version]).encode()).hexdigest()[:16]


def _build(name: str, src: str, flags: tuple[str, ...], target: Path) -> None:
    """Compile ``src`` into the shared library ``target`` (in the cache), atomically."""
    cache = target.parent
    _remove_stale(cache)
    _remove_stale_temp_dirs()
    cc = os.environ.get("CC", "gcc")
    if shutil.which(cc) is None:
        raise NoCompiler(errno.ENOENT, f"no C compiler: {cc!r} is not a program on this machine "
                         "(install gcc, or set CC to a C compiler); the closed-loop lap then runs "
                         "on CasADi's virtual machine, slower, and the limit lap needs one")
    announce = len(src) >= ANNOUNCE_CHARS or sys.stderr.isatty()
    if announce:
        emit("compile", f"compiling {name} ({len(src) // 1000} kB of C from CasADi) once for "
             f"this machine, cached in {cache}; a large one takes a minute or more")
    cpu0 = children_cpu_seconds()  # the compiler is a child process
    try:
        with tempfile.TemporaryDirectory(prefix=TEMP_PREFIX) as tmp:  # removed on any exit
            c_file, so_file = Path(tmp) / f"{name}.c", Path(tmp) / f"{name}.so"
            c_file.write_text(src)
            run_compiler([cc, *flags, "-shared", "-fPIC", str(c_file), "-o", str(so_file),
                          "-lm"])
            _install(so_file, target, name, cache)
        if announce:
            cpu = children_cpu_seconds() - cpu0
            emit("compile", f"compiled {name} ({cpu:.1f} s CPU of the compiler)", cpu_s=cpu)
    except _Terminated:  # cleaned up: now end as SIGTERM would have ended the process
        _terminated_again()
        raise


def _install(so_file: Path, target: Path, name: str, cache: Path) -> None:
    fd, staged = tempfile.mkstemp(prefix=f".{name}_", suffix=".tmp", dir=cache)
    try:
        with os.fdopen(fd, "wb") as out:
            out.write(so_file.read_bytes())
        os.chmod(staged, 0o755)
        os.replace(staged, target)  # atomic: readers see the old name absent or complete
    finally:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(staged)


class _Terminated(BaseException):
    """SIGTERM arrived while the compiler ran (re-delivered after the cleanup)."""


#: The compiler's process-group leader: a POSIX shell that runs the compiler command (its
#: arguments) and, on SIGTERM, SIGKILLs its whole group (itself, the gcc driver, ``cc1``, ``as``).
#: The kernel sends it SIGTERM when casadrone dies (prctl PR_SET_PDEATHSIG, which reaches only
#: the process that asked, never the driver's own children: with the signal on the driver alone,
#: ``cc1`` ran on after a SIGKILL of casadrone). Its exit status is the compiler's.
GROUP_LEADER = ("/bin/sh", "-c", 'trap "kill -s KILL 0" TERM; "$@" & wait $!', "casadrone-cc")


def _death_signal_setter():
    """A function for ``preexec_fn`` that asks Linux to send SIGTERM to the compiler's group
    leader (:data:`GROUP_LEADER`) when casadrone dies (prctl PR_SET_PDEATHSIG), prepared before
    the fork (nothing is imported in the child); a child whose parent died before the request
    exits at once. None elsewhere."""
    if not sys.platform.startswith("linux"):
        return None
    try:
        import ctypes

        prctl = ctypes.CDLL(None, use_errno=True).prctl
    except (OSError, AttributeError):
        return None
    parent = os.getpid()

    def set_death_signal() -> None:
        prctl(1, signal.SIGTERM, 0, 0, 0)
        if os.getppid() != parent:  # casadrone died before the request: nothing would signal
            os._exit(1)

    return set_death_signal


def run_compiler(command: list[str]) -> None:
    """Run a compiler command in a process group of its own, led by :data:`GROUP_LEADER`; on any
    exception or signal kill the whole group (driver and its cc1/as children) and wait for it,
    then pass it on; if casadrone dies unseen (SIGKILL), the leader kills the group.

    Raises CalledProcessError (with the compiler's output) when the compiler fails.
    """
    handler = None
    main = threading.current_thread() is threading.main_thread()
    if main and signal.getsignal(signal.SIGTERM) is signal.SIG_DFL:
        def handler(signum, frame):
            raise _Terminated

        signal.signal(signal.SIGTERM, handler)
    proc = None
    try:
        proc = subprocess.Popen([*GROUP_LEADER, *command], stdout=subprocess.PIPE,
                                stderr=subprocess.STDOUT, start_new_session=True,
                                preexec_fn=_death_signal_setter())
        out, _ = proc.communicate()
        if proc.returncode:
            raise subprocess.CalledProcessError(proc.returncode, command, out)
    except BaseException:
        if proc is not None and proc.poll() is None:
            with contextlib.suppress(ProcessLookupError, PermissionError):
                os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
        raise
    finally:
        if handler is not None:
            signal.signal(signal.SIGTERM, signal.SIG_DFL)


def _terminated_again() -> None:
    """Deliver SIGTERM again, now with its default action (the process ends as it would have)."""
    os.kill(os.getpid(), signal.SIGTERM)


def _remove_stale_temp_dirs(age_s: float = 3600.0) -> None:
    """Remove compile folders (``casadrone-cc-*``) that a SIGKILLed process left in the
    temporary directory more than ``age_s`` ago (a compile in progress is younger)."""
    now = time.time()
    for folder in Path(tempfile.gettempdir()).glob(f"{TEMP_PREFIX}*"):
        with contextlib.suppress(OSError):
            if folder.is_dir() and now - folder.stat().st_mtime > age_s:
                shutil.rmtree(folder, ignore_errors=True)


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


def compile_with_reverse(fun: ca.Function, flags: tuple[str, ...] = DEFAULT_FLAGS
                         ) -> ca.Function:
    """:func:`compile_function` with ``fun``'s first reverse derivative in the same library
    (``adj1_<name>``, which CasADi's external loads with it), so that reverse-mode AD of a graph
    that calls the compiled function passes through compiled code too. Both are CasADi's own
    code generation of the same algorithm its virtual machine runs: the same operations in the
    same order, so the same numbers to the last bit (tests/unit/test_codegen.py)."""
    gen = ca.CodeGenerator(f"{fun.name()}.c", {"with_header": False})
    gen.add(fun)
    gen.add(fun.reverse(1))
    return ca.external(fun.name(), str(compile_source(fun.name(), gen.dump(), flags)))


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
                buf.set_arg(i, memoryview(a))  # type: ignore[call-arg, arg-type]  # casadi's stub
            for i, o in enumerate(outs):
                buf.set_res(i, memoryview(o.reshape(-1)))  # type: ignore[call-arg, arg-type]
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


def recipe_fingerprint(fun: ca.Function, *builders: Callable) -> str:
    """What determines the C that ``builders`` generate from ``fun``: ``fun`` serialised (its whole
    expression graph, model and parameters included; a few ms) and the builders' source text.
    Code that is not source here (a frozen build) falls back to its marshalled bytecode."""
    parts = [fun.serialize()]
    for builder in builders:
        try:
            parts.append(inspect.getsource(builder))
        except (OSError, TypeError):
            parts.append(marshal.dumps(builder.__code__).hex())
    return hashlib.sha256("\0".join(parts).encode()).hexdigest()


def compile_recipe(names: tuple[str, ...], fingerprint: str,
                   build: Callable[[], Sequence[ca.Function]],
                   flags: tuple[str, ...] = DEFAULT_FLAGS) -> list[ca.Function]:
    """The functions ``names``, compiled together into one library that the cache finds by
    ``fingerprint`` (:func:`recipe_fingerprint` of what determines them) instead of by their C
    source: a process that finds the library never calls ``build`` (which returns the functions,
    in the order of ``names``) nor generates their C. For the limit lap's interval blocks that is
    1-3 s of CPU in every process (CasADi's code generator on a ~10⁵-line Hessian), most of what a
    cached process pays before its first solve. On a miss, ``build()`` is compiled as
    :func:`compile_source` does (the same atomic install), under the fingerprint's name."""
    target = cache_dir() / f"{names[0]}_r{_digest('recipe', fingerprint, *names, *flags)}.so"
    if not target.exists():
        gen = ca.CodeGenerator(f"{names[0]}.c", {"with_header": False})
        built = list(build())
        if [f.name() for f in built] != list(names):
            raise ValueError(f"build() returned {[f.name() for f in built]}, not {list(names)}")
        for f in built:
            gen.add(f)
        _build(names[0], gen.dump(), flags, target)
    return [ca.external(n, str(target)) for n in names]
