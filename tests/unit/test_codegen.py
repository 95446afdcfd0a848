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

from casadrone.airframe import build_airframe
from casadrone.codegen import (
    ZeroCopyCall,
    compile_function,
    compile_recipe,
    compile_with_reverse,
    has_avx2,
    recipe_fingerprint,
    vector_flags,
)
from casadrone.config.airframe import load_airframe

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



def _probe_builder(scale: float):
    x = ca.SX.sym("x", 2)
    y = ca.vertcat(ca.exp(x[0]) * x[1], ca.atan2(x[1], x[0])) * scale
    return [ca.Function("probe_recipe", [x], [y]),
            ca.Function("probe_recipe_jac", [x], [ca.jacobian(y, x)])]


def _other_builder(scale: float):
    return _probe_builder(2 * scale)


def test_a_cached_recipe_is_found_without_building_it(tmp_path, monkeypatch):
    """compile_recipe compiles build() once; a second call with the same fingerprint loads the
    library without calling build (it raises here) and gives the virtual machine's numbers bit
    for bit; a changed function or builder changes the fingerprint, so it is built again."""
    monkeypatch.setenv("CASADRONE_CACHE", str(tmp_path))
    x = ca.SX.sym("x")
    key_fun = ca.Function("key", [x], [ca.sin(x)])
    fp = recipe_fingerprint(key_fun, _probe_builder)
    names = ("probe_recipe", "probe_recipe_jac")
    calls = []

    def build():
        calls.append(1)
        return _probe_builder(1.0)

    first = compile_recipe(names, fp, build)

    def refuse():
        raise AssertionError("build() called although the library is cached")

    second = compile_recipe(names, fp, refuse)
    assert calls == [1]
    assert [f.class_name() for f in second] == ["External", "External"]
    for v in ([0.3, -1.2], [2.0, 0.5]):
        for vm, a, b in zip(_probe_builder(1.0), first, second, strict=True):
            np.testing.assert_array_equal(np.array(a(v)), np.array(vm(v)))
            np.testing.assert_array_equal(np.array(b(v)), np.array(vm(v)))
    assert recipe_fingerprint(key_fun, _other_builder) != fp
    assert recipe_fingerprint(ca.Function("key", [x], [ca.cos(x)]), _probe_builder) != fp
    assert recipe_fingerprint(ca.Function("key", [x], [ca.sin(x)]), _probe_builder) == fp
    compile_recipe(names, recipe_fingerprint(key_fun, _other_builder), build)
    assert calls == [1, 1]
    with pytest.raises(ValueError, match="probe_recipe_jac"):
        compile_recipe(names[::-1], "another", build)


def test_interval_blocks_from_the_cache_equal_their_sx(tmp_path, monkeypatch):
    """The limit lap's interval blocks found by fingerprint (a fresh process: nothing built) give
    the uncompiled SX functions' values and the Hessian pattern of the SX Hessian."""
    monkeypatch.setenv("CASADRONE_CACHE", str(tmp_path))
    from casadrone.limit import nlp

    model = nlp.point_mass_ocp_model()
    nlp.interval_blocks(model, 1)
    nlp._BLOCKS.clear()

    def refuse(*args, **kwargs):
        raise AssertionError("a cache hit builds the Hessian or generates C")

    monkeypatch.setattr(ca, "hessian", refuse)
    monkeypatch.setattr(ca, "CodeGenerator", refuse)
    jac, hess, rows, cols = nlp.interval_blocks(model, 1)
    monkeypatch.undo()
    sx_jac, sx_hess, _ = nlp.interval_block_functions(model, 1)
    z = ca.SX.sym("z", 1 + model.nu + model.nx)
    lam = ca.SX.sym("lam", model.nx)
    step = nlp.rk4_step(model, 1)
    x_next = step(z[1 + model.nu:], z[1:1 + model.nu], ca.SX.sym("p", model.np), z[0] * 0.1)
    H = ca.triu(ca.hessian(ca.dot(lam, x_next), z)[0])
    r, c = H.sparsity().get_triplet()
    assert len(rows) > 0
    np.testing.assert_array_equal(rows, r)
    np.testing.assert_array_equal(cols, c)
    rng = np.random.default_rng(0)
    args = [rng.uniform(0.5, 1.5, 1 + model.nu + model.nx), rng.uniform(0.5, 1.5, model.np),
            0.1, rng.normal(size=model.nx)]
    for a, b in zip(jac(*args[:3]), sx_jac(*args[:3]), strict=True):
        np.testing.assert_array_equal(np.array(a), np.array(b))
    np.testing.assert_array_equal(np.array(hess(*args)), np.array(sx_hess(*args)))

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


def test_avx2_is_read_from_the_flags_line_as_a_whole_word():
    assert has_avx2("processor\t: 0\nflags\t\t: fpu sse2 avx avx2 fma\n")
    assert not has_avx2("flags\t\t: fpu sse2 avx avx512f\n")  # avx512f is not avx2
    assert not has_avx2("model name\t: avx2 in a name\nflags\t\t: fpu sse2\n")
    assert not has_avx2("")


def test_the_quadrotor_blocks_in_vector_registers_keep_every_bit():
    """The limit lap's interval blocks compiled with BLOCK_FLAGS (-O2, AVX2 where the CPU has it)
    give CasADi's virtual machine's numbers to the last bit over many random intervals: vector
    instructions without FMA round each operation as the scalar code does (IEEE 754), so the
    flags change the speed, never an iterate."""
    from casadrone.limit import nlp

    model = nlp.quadrotor_ocp_model()
    jac, hess, _, _ = nlp.interval_blocks(model, 3)  # the default design's, compiled
    sx_jac, sx_hess, _ = {"substep-chain": nlp.chained_block_functions,
                          "whole-step": nlp.interval_block_functions}[nlp.block_design()](
        model, 3)
    step = nlp.step_block(model, 3)
    assert hess.class_name() == "External" and step.class_name() == "External"
    assert nlp.BLOCK_FLAGS[1:] == vector_flags()
    rng = np.random.default_rng(7)
    n = 64
    z = rng.uniform(-1.0, 1.0, (1 + model.nu + model.nx, n))
    z[0] = rng.uniform(0.5, 4.0, n)  # leg durations
    p = rng.uniform(0.5, 1.5, model.np)  # positive: masses, inertias, gains
    lam = rng.normal(size=(model.nx, n))
    for compiled, sx, args in ((jac, sx_jac, (z, p, 0.025)), (hess, sx_hess, (z, p, 0.025, lam))):
        got = [np.array(v) for v in compiled.map(n).call(list(args))]
        want = [np.array(v) for v in sx.map(n).call(list(args))]
        assert np.abs(want[-1]).max() > 1e-3
        for a, b in zip(got, want, strict=True):
            np.testing.assert_array_equal(a, b)
    x, u = z[1 + model.nu:], z[1:1 + model.nu]
    sx_step = nlp.rk4_step(model, 3)
    np.testing.assert_array_equal(np.array(step.map(n)(x, u, p, z[0] * 0.025)),
                                  np.array(sx_step.map(n)(x, u, p, z[0] * 0.025)))


@pytest.mark.parametrize("which", ["point-mass", "quadrotor", "quadrotor-propeller",
                                   pytest.param("quadrotor-propeller-etd",
                                                marks=pytest.mark.slow)])
def test_chained_interval_blocks_are_the_whole_steps_derivatives(which):
    """The interval blocks chain one RK4 step's derivatives over the interval's three steps,
    each step's from its four stages (the right-hand side's derivatives, chained); CasADi's
    symbolic Jacobian and Hessian of the whole interval (three steps in one SX graph: an
    independent oracle) give the same numbers to rounding, at random points, for classical RK4
    (the paper's and the propeller's models) and for the exponential rotor step (ETDRK4, whose
    h also enters the φ functions: chained by steps only)."""
    from casadrone.limit import nlp

    model = {"point-mass": lambda: nlp.point_mass_ocp_model(),
             "quadrotor": lambda: nlp.quadrotor_ocp_model(),
             "quadrotor-propeller": lambda: nlp.quadrotor_ocp_model("propeller"),
             "quadrotor-propeller-etd": lambda: nlp.exponential_rotor(
                 nlp.quadrotor_ocp_model("propeller"))}[which]()
    nx, nu = model.nx, model.nu
    jac, hess, pattern = nlp.chained_block_functions(model, 3)
    z = ca.SX.sym("z", 1 + nu + nx)
    p, inv_n, lam = ca.SX.sym("p", model.np), ca.SX.sym("inv_n"), ca.SX.sym("lam", nx)
    x_next = nlp.rk4_step(model, 3)(z[1 + nu:], z[1:1 + nu], p, z[0] * inv_n)
    H = ca.triu(ca.hessian(ca.dot(lam, x_next), z)[0])
    oracle = ca.Function("oracle", [z, p, inv_n, lam],
                         [x_next, ca.jacobian(x_next, z), ca.vertcat(*H.nonzeros())])
    r, c = H.sparsity().get_triplet()
    rows, cols = (np.asarray(a, dtype=int).ravel() for a in pattern.call([]))
    np.testing.assert_array_equal(rows, r)
    np.testing.assert_array_equal(cols, c)
    rng = np.random.default_rng(3)
    # the propeller model at SY250-propeller's parameters and rotor speeds near 2000 rad/s (its
    # rotor states in krad/s, model.scale); random parameters of O(1) make its rotors diverge
    p_of = (np.asarray(build_airframe(load_airframe("SY250-propeller")).p, float)
            if model.propulsion == "propeller" else None)
    for _ in range(5):
        zz = rng.uniform(-1.0, 1.0, 1 + nu + nx)
        zz[0] = rng.uniform(0.5, 4.0)  # leg duration (s)
        pp = rng.uniform(0.5, 1.5, model.np) if p_of is None else p_of
        if p_of is not None:
            zz[1:1 + nu] = rng.uniform(0.2, 1.0, nu)  # ESC commands
            zz[1 + nu + 12:] = rng.uniform(1.5, 2.5, 4)
        args = (zz, pp, 0.025, rng.normal(size=nx))
        want = [np.array(v) for v in oracle(*args)]
        got = [np.array(v) for v in (*jac(*args[:3]), hess(*args))]
        assert np.abs(want[2]).max() > 1e-3
        for a, b in zip(got, want, strict=True):
            np.testing.assert_allclose(a, b, rtol=0, atol=1e-12 * np.abs(b).max())


@pytest.mark.parametrize("which", ["point-mass", "quadrotor", "quadrotor-propeller"])
def test_chained_theta_blocks_are_the_whole_steps_derivatives(which):
    """Co-design's θ-blocks, chained over the interval's three RK4 steps (the propeller model's
    steps from their four stages), against CasADi's symbolic derivatives of the whole interval
    along the directions D (p + Dσ, σ = 0): the same numbers to rounding at random points (the
    propeller model's near SY250-propeller's parameters, as in the limit lap's test above)."""
    from casadrone.codesign.blocks import chained_theta_block_functions
    from casadrone.limit import nlp

    model = {"point-mass": nlp.point_mass_ocp_model, "quadrotor": nlp.quadrotor_ocp_model,
             "quadrotor-propeller": lambda: nlp.quadrotor_ocp_model("propeller")}[which]()
    p_of = (np.asarray(build_airframe(load_airframe("SY250-propeller")).p, float)
            if model.propulsion == "propeller" else None)
    nx, nu, nd = model.nx, model.nu, 4
    jac, hess = chained_theta_block_functions(model, 3, nd)
    z = ca.SX.sym("z", 1 + nu + nx)
    p, inv_n, lam = ca.SX.sym("p", model.np), ca.SX.sym("inv_n"), ca.SX.sym("lam", nx)
    D, sig = ca.SX.sym("D", model.np, nd), ca.SX.sym("sig", nd)
    x_next = nlp.rk4_step(model, 3)(z[1 + nu:], z[1:1 + nu], p + ca.mtimes(D, sig),
                                    z[0] * inv_n)
    L = ca.dot(lam, x_next)
    H = ca.hessian(L, ca.vertcat(z, sig))[0]
    outs = [ca.jacobian(x_next, sig).T, H[:z.numel(), z.numel():].T, H[z.numel():, z.numel():],
            ca.gradient(L, p)]
    oracle = ca.Function("oracle", [z, p, inv_n, lam, D, sig], outs)
    rng = np.random.default_rng(5)
    for _ in range(3):
        zz = rng.uniform(-1.0, 1.0, 1 + nu + nx)
        zz[0] = rng.uniform(0.5, 4.0)
        pp, ll, dd = rng.uniform(0.5, 1.5, model.np), rng.normal(size=nx), \
            rng.normal(size=(model.np, nd))
        if p_of is not None:  # physical parameters, commands and rotor speeds (krad/s)
            pp, dd = p_of, 1e-3 * np.abs(p_of)[:, None] * dd
            zz[1:1 + nu] = rng.uniform(0.2, 1.0, nu)
            zz[1 + nu + 12:] = rng.uniform(1.5, 2.5, 4)
        want = [np.array(v) for v in oracle(zz, pp, 0.025, ll, dd, np.zeros(nd))]
        got = [np.array(jac(zz, pp, 0.025, dd)), *(np.array(v) for v in hess(zz, pp, 0.025,
                                                                               ll, dd))]
        for a, b in zip(got, want, strict=True):
            assert a.shape == b.shape and np.abs(b).max() > 1e-6
            np.testing.assert_allclose(a, b, rtol=0, atol=1e-12 * np.abs(b).max())


def test_the_blocks_design_is_the_substep_chain_unless_chosen(monkeypatch):
    """``$CASADRONE_BLOCKS`` chooses the interval blocks' design; unset, the substep chain (a
    fifth of the C); whole-step gives every lap as before, to the bit; another value is refused
    naming the variable."""
    from casadrone.limit import nlp

    monkeypatch.delenv("CASADRONE_BLOCKS", raising=False)
    assert nlp.block_design() == "substep-chain"
    monkeypatch.setenv("CASADRONE_BLOCKS", "whole-step")
    assert nlp.block_design() == "whole-step"
    monkeypatch.setenv("CASADRONE_BLOCKS", "chain")
    with pytest.raises(ValueError, match="CASADRONE_BLOCKS"):
        nlp.block_design()
