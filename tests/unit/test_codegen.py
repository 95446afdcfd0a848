"""Compile cache (private temporary directory, atomic install, nothing in the working directory)
and zero-copy calls (one set of buffers per thread)."""

import os
import subprocess
import sys
import threading
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from casadrone.codegen import ZeroCopyCall, compile_function, compile_with_reverse

ROOT = Path(__file__).resolve().parents[2]

SNIPPET = """
import casadi as ca, numpy as np, sys
from casadrone.codegen import compile_function
x = ca.SX.sym("x", 3)
f = compile_function(ca.Function("race_probe", [x], [ca.sin(x) * {k} + x ** 2]))
print(f.class_name(), float(np.sum(np.array(f([0.1, 0.2, 0.3])))))
"""


def test_concurrent_cold_compiles_share_one_library(tmp_path):
    """Four processes compile the same Function into one cold cache at the same time (Dask
    workers starting cold): every one loads a complete library and gets the right values; one
    library is left, no staged file, and nothing is written to their working directory."""
    cwd = tmp_path / "cwd"
    cwd.mkdir()
    env = {**os.environ, "CASADRONE_CACHE": str(tmp_path / "cache"),
           "PYTHONPATH": str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", "")}
    procs = [subprocess.Popen([sys.executable, "-c", SNIPPET.format(k=2.0)], cwd=cwd, env=env,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
             for _ in range(4)]
    outs = [p.communicate(timeout=300) for p in procs]
    x = np.array([0.1, 0.2, 0.3])
    expected = float(np.sum(np.sin(x) * 2.0 + x**2))
    for (out, err), p in zip(outs, procs, strict=True):
        assert p.returncode == 0, err
        kind, value = out.split()
        assert kind == "External"
        assert float(value) == pytest.approx(expected, rel=1e-14)
    assert len(list((tmp_path / "cache").glob("race_probe_*.so"))) == 1
    assert not list((tmp_path / "cache").glob("*.tmp"))
    assert not list(cwd.iterdir())


def test_compiled_function_equals_virtual_machine(tmp_path, monkeypatch):
    monkeypatch.setenv("CASADRONE_CACHE", str(tmp_path))
    x = ca.SX.sym("x", 2)
    f = ca.Function("probe_vm", [x], [ca.vertcat(ca.exp(x[0]) * x[1], ca.atan2(x[1], x[0]))])
    c = compile_function(f)
    assert c.class_name() == "External"
    for v in ([0.3, -1.2], [2.0, 0.5]):
        np.testing.assert_array_equal(np.array(c(v)), np.array(f(v)))


def test_compiled_reverse_equals_virtual_machine(tmp_path, monkeypatch):
    """A graph that calls the function compiled with its reverse derivative gives the values and
    the gradient (reverse AD through the compiled adj1_) of the virtual machine's, bit for bit,
    mapped over columns as the limit lap's rows map the step."""
    monkeypatch.setenv("CASADRONE_CACHE", str(tmp_path))
    x, q = ca.SX.sym("x", 2), ca.SX.sym("q")
    f = ca.Function("probe_rev", [x, q], [ca.vertcat(ca.exp(x[0]) * x[1] / q,
                                                     ca.atan2(x[1], x[0]) * ca.sin(q))])
    c = compile_with_reverse(f)
    assert c.class_name() == "External"
    X, Q = ca.MX.sym("X", 2, 3), ca.MX.sym("Q", 1, 3)
    lam = ca.DM([[0.7, -1.3, 2.1], [0.4, 0.9, -0.2]])
    values = []
    for fun in (f, c):
        y = fun.map(3)(X, Q)
        L = ca.dot(lam, y)
        g = ca.Function("g", [X, Q], [y, ca.gradient(L, X), ca.gradient(L, Q)])
        values.append([np.array(v) for v in g(np.array([[0.3, -1.2, 2.0], [0.5, 1.1, -0.4]]),
                                               np.array([[1.5, 0.2, 3.0]]))])
    assert np.abs(values[0][1]).max() > 0.1
    for vm, compiled in zip(*values, strict=True):
        np.testing.assert_array_equal(compiled, vm)


def test_zero_copy_call_is_per_thread():
    """Eight threads call one ZeroCopyCall with different inputs at once: each gets its own
    results (one set of bound buffers per thread)."""
    x = ca.SX.sym("x", 3)
    f = ca.Function("zc", [x], [ca.vertcat(ca.sum1(x), x[0] * x[1] * x[2])])
    call = ZeroCopyCall(f)
    errors: list[str] = []

    def work(seed):
        rng = np.random.default_rng(seed)
        for _ in range(2000):
            v = rng.random(3)
            (out,) = call(v)
            got = out.ravel().copy()
            want = [v.sum(), v[0] * v[1] * v[2]]
            if not np.allclose(got, want, rtol=1e-15, atol=0):
                errors.append(f"thread {seed}: {got} != {want}")
                return

    threads = [threading.Thread(target=work, args=(i,)) for i in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors, errors[:3]


def test_zero_copy_call_refuses_sparse_outputs():
    x = ca.SX.sym("x", 2)
    with pytest.raises(ValueError, match="sparse"):
        ZeroCopyCall(ca.Function("sp", [x], [ca.jacobian(x**2, x)]))


def test_stale_staged_files_are_removed_by_the_next_compile(tmp_path, monkeypatch):
    """A staged file left by a killed process (older than an hour) goes at the next compile; a
    young one (a compile in progress elsewhere) stays."""
    monkeypatch.setenv("CASADRONE_CACHE", str(tmp_path))
    old, young = tmp_path / ".lap_step_driver_abc.tmp", tmp_path / ".other_def.tmp"
    old.write_bytes(b"half")
    young.write_bytes(b"half")
    two_hours_ago = old.stat().st_mtime - 7200
    os.utime(old, (two_hours_ago, two_hours_ago))
    x = ca.SX.sym("x")
    compile_function(ca.Function("probe_stale", [x], [3 * x]))
    assert not old.exists() and young.exists()
