"""``python -m casadrone.precompile``: the libraries it compiles side by side are the ones the
first use of each model would compile (same names in the same cache), so later uses find them."""

from __future__ import annotations

from pathlib import Path

from casadrone.limit import nlp
from casadrone.precompile import SHIPPED, Block, main, precompile

ROOT = Path(__file__).resolve().parents[2]


def test_precompile_puts_each_library_where_its_first_use_would(tmp_path, monkeypatch):
    """Compiled in a child process by precompile into one cache, and by the limit lap's own first
    use in this process into another: the same files. Then this process, asked again with the
    first cache, builds no Hessian and generates no C (a cache hit by fingerprint)."""
    import casadi as ca

    pre, use = tmp_path / "pre", tmp_path / "use"
    block = Block("limit", "point-mass")
    monkeypatch.setenv("CASADRONE_CACHE", str(pre))
    done = precompile((block,), jobs=1)
    assert [b for b, _ in done] == [block]
    monkeypatch.setenv("CASADRONE_CACHE", str(use))
    monkeypatch.setattr(nlp, "_BLOCKS", {})
    monkeypatch.setattr(nlp, "_STEPS", {})
    model = nlp.point_mass_ocp_model()
    nlp.step_block(model, 3)
    nlp.interval_blocks(model, 3)
    names = sorted(p.name for p in pre.glob("*.so"))
    assert len(names) == 2  # the compiled step and the interval blocks
    assert names == sorted(p.name for p in use.glob("*.so"))

    monkeypatch.setenv("CASADRONE_CACHE", str(pre))
    monkeypatch.setattr(nlp, "_BLOCKS", {})

    def refuse(*args, **kwargs):
        raise AssertionError("a precompiled library was not found: built or generated again")

    monkeypatch.setattr(ca, "hessian", refuse)
    monkeypatch.setattr(ca, "CodeGenerator", refuse)
    jac, hess, rows, cols = nlp.interval_blocks(model, 3)
    assert hess.class_name() == "External"


def test_jobs_below_one_is_refused(capsys):
    assert main(["--jobs", "0"]) == 2
    err = capsys.readouterr().err
    assert "--jobs" in err and err.count("\n") == 1


def test_without_a_compiler_it_says_so_in_one_line(tmp_path, monkeypatch, capsys):
    """No C compiler: exit 1 and the compiler's absence named in one line, no traceback (the
    first compile fails in its child process; the others are cancelled)."""
    monkeypatch.setenv("CASADRONE_CACHE", str(tmp_path))
    monkeypatch.setenv("CC", str(tmp_path / "no-such-cc"))
    assert main(["--jobs", "1"]) == 1
    err = capsys.readouterr().err
    assert "no C compiler" in err and "no-such-cc" in err and err.count("\n") == 1
    assert not list(tmp_path.glob("*.so"))


def test_every_shipped_codesign_problem_finds_its_theta_blocks_precompiled():
    """The θ-blocks' library depends on the number of design variables (``n_dir``) and on the
    airframe's propulsion kind: each shipped co-design problem's must be in SHIPPED, or the first
    co-design run on a precompiled machine still compiles for minutes."""
    from casadrone.codesign.checks import load_codesign_problem
    from casadrone.config.airframe import load_airframe

    paths = sorted((ROOT / "problems").glob("codesign-*.yaml"))
    assert len(paths) >= 4
    for path in paths:
        problem = load_codesign_problem(path)
        propulsion = load_airframe(problem.airframe).propulsion.model
        want = Block("codesign", "quadrotor", propulsion, n_dir=len(problem.variables))
        assert want in SHIPPED, (path.name, want)


def test_each_block_is_reported_ready_with_its_count_and_time():
    """``block k/n ready`` as each compile ends: k counts the blocks done so far."""
    from casadrone.precompile import ready_lines

    lines: list[str] = []
    ready = ready_lines(3, lines.append)
    ready(Block("limit", "point-mass"), 1.3)
    ready(Block("codesign", "quadrotor", "propeller"), 241.0)
    assert lines == ["block 1/3 ready: limit point-mass paper rk4x3 (1.3 s wall)",
                     "block 2/3 ready: codesign quadrotor propeller rk4x3 (d4) (241.0 s wall)"]


def test_main_says_each_block_ready_on_stderr_and_nothing_with_quiet(tmp_path, monkeypatch,
                                                                     capsys):
    """A point-mass block (seconds) into an empty cache: nothing on stderr with -q; without it
    one ``block 1/1 ready`` line on stderr, the total on stdout."""
    import re

    import casadrone.precompile as pre

    monkeypatch.setenv("CASADRONE_CACHE", str(tmp_path))
    monkeypatch.setattr(pre, "SHIPPED", (Block("limit", "point-mass"),))
    assert main(["--jobs", "1", "-q"]) == 0
    assert capsys.readouterr().err == ""
    assert len(list(tmp_path.glob("*.so"))) == 2  # it did compile
    assert main(["--jobs", "1"]) == 0
    loud = capsys.readouterr()
    assert re.fullmatch(r"block 1/1 ready: limit point-mass paper rk4x3 \(\d+\.\d s wall\)\n",
                        loud.err)
    assert loud.out.startswith("all 1 in ")
