"""A compile ends with its command (issue 20, point 6): SIGTERM during a compile kills the whole
compiler process group and leaves no temporary folder, the first compile of a large source says
what it does, and a missing compiler is named as such. A fake compiler (a shell script that forks
a long-lived child, as gcc forks cc1) stands in for gcc, so the test takes seconds."""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from casadrone import codegen

ROOT = Path(__file__).resolve().parents[2]


def alive(pid: int) -> bool:
    """True while ``pid`` runs (a zombie awaiting its reaper counts as ended)."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (FileNotFoundError, IndexError):
        return False
    return state != "Z"


@pytest.fixture
def env(tmp_path):
    (tmp_path / "tmp").mkdir()
    return {**os.environ, "PYTHONPATH": str(ROOT), "CASADRONE_CACHE": str(tmp_path / "cache"),
            "TMPDIR": str(tmp_path / "tmp")}


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_sigterm_during_a_compile_kills_the_compiler_and_removes_its_folder(tmp_path, env):
    cc = tmp_path / "slowcc"
    mark = tmp_path / "pids"
    cc.write_text(f'#!/bin/sh\nsleep 300 &\necho "$$ $!" > "{mark}.tmp"\nmv "{mark}.tmp" '
                  f'"{mark}"\nwait\n')
    cc.chmod(0o755)
    child = subprocess.Popen([sys.executable, "-c", "from casadrone.codegen import compile_source;"
                              " compile_source('t', 'int x;')"], env={**env, "CC": str(cc)})
    deadline = time.monotonic() + 60
    while not mark.exists():
        assert child.poll() is None and time.monotonic() < deadline, "the compiler never started"
        time.sleep(0.05)
    driver, grandchild = (int(p) for p in mark.read_text().split())
    assert alive(driver) and alive(grandchild)
    child.send_signal(signal.SIGTERM)
    assert child.wait(timeout=30) == -signal.SIGTERM  # ends as SIGTERM ends a process
    deadline = time.monotonic() + 10
    while (alive(driver) or alive(grandchild)) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not alive(driver) and not alive(grandchild), "the compiler outlived its command"
    assert list((tmp_path / "tmp").iterdir()) == []  # no casadrone-cc-* folder left


def fake_cc(tmp_path: Path) -> Path:
    """A 'compiler' that writes an empty output file (the library is not loaded here)."""
    cc = tmp_path / "fakecc"
    cc.write_text('#!/bin/sh\nwhile [ "$1" != "-o" ]; do shift; done\n: > "$2"\n')
    cc.chmod(0o755)
    return cc


def test_a_large_first_compile_says_what_it_does(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("CC", str(fake_cc(tmp_path)))
    monkeypatch.setenv("CASADRONE_CACHE", str(tmp_path / "cache"))
    src = "/* padding */\n" * (codegen.ANNOUNCE_CHARS // 14 + 1) + "int x;\n"
    target = codegen.compile_source("big", src)
    err = capsys.readouterr().err
    assert "compiling big" in err and "once for this machine" in err
    assert "compiled big (" in err.splitlines()[-1]  # and when it is done, with its CPU
    assert codegen.compile_source("big", src) == target  # cached: silent the second time
    assert capsys.readouterr().err == ""


def test_no_compiler_is_named_as_such(tmp_path, monkeypatch):
    from casadrone.cli.common import one_line

    monkeypatch.setenv("CC", "nogcc")
    monkeypatch.setenv("CASADRONE_CACHE", str(tmp_path / "cache"))
    with pytest.raises(codegen.NoCompiler) as err:
        codegen.compile_source("t", "int x;")
    line = one_line(err.value)
    assert line.startswith("no C compiler: 'nogcc' is not a program") and "set CC" in line
    assert "No such file or directory" not in line


def test_a_folder_left_by_a_killed_compile_is_removed_an_hour_later(tmp_path, monkeypatch):
    monkeypatch.setenv("CC", str(fake_cc(tmp_path)))
    monkeypatch.setenv("CASADRONE_CACHE", str(tmp_path / "cache"))
    monkeypatch.setattr(codegen.tempfile, "tempdir", str(tmp_path))
    old, young = tmp_path / "casadrone-cc-old", tmp_path / "casadrone-cc-young"
    for folder in (old, young):
        folder.mkdir()
    os.utime(old, (time.time() - 7200, time.time() - 7200))
    codegen.compile_source("t2", "int y;")
    assert not old.exists() and young.exists()  # a compile in progress elsewhere is younger


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_a_stopped_runs_compiling_worker_leaves_no_compiler_and_no_folder(tmp_path, env,
                                                                         monkeypatch):
    from casadrone.optimise.backends import ProcessBackend

    cc = tmp_path / "slowcc"
    mark = tmp_path / "pids"
    cc.write_text(f'#!/bin/sh\nsleep 300 &\necho "$$ $!" > "{mark}.tmp"\nmv "{mark}.tmp" '
                  f'"{mark}"\nwait\n')
    cc.chmod(0o755)
    for key in ("CASADRONE_CACHE", "TMPDIR"):
        monkeypatch.setenv(key, env[key])
    monkeypatch.setenv("CC", str(cc))
    backend = ProcessBackend(1)  # spawned: the worker reads this environment
    try:
        backend.pool.submit(codegen.compile_source, "w", "int w;")
        deadline = time.monotonic() + 120
        while not mark.exists():
            assert time.monotonic() < deadline, "the worker's compiler never started"
            time.sleep(0.05)
        driver, grandchild = (int(p) for p in mark.read_text().split())
    finally:
        backend.terminate()  # as a stopped run ends its pool
    deadline = time.monotonic() + 10
    while (alive(driver) or alive(grandchild)) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not alive(driver) and not alive(grandchild)
    assert list((tmp_path / "tmp").iterdir()) == []


def descendants(pid: int) -> dict[int, str]:
    """Every process below ``pid`` (pid → command name), read from /proc."""
    parent_of, name_of = {}, {}
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                head, tail = (entry / "stat").read_text().rsplit(")", 1)
            except (FileNotFoundError, ProcessLookupError):
                continue
            parent_of[int(entry.name)] = int(tail.split()[1])
            name_of[int(entry.name)] = head.partition("(")[2]
    found, frontier = {}, [pid]
    while frontier:
        here = frontier.pop()
        for child, parent in parent_of.items():
            if parent == here and child not in found:
                found[child] = name_of[child]
                frontier.append(child)
    return found


def slow_c_source(statements: int = 20000) -> str:
    """One function of ``statements`` dependent floating-point updates: gcc -O2 spends minutes
    in cc1 on it (measured: over 120 s for 20000), so cc1 is surely running when it is killed."""
    body = [f"  s += x[{i % 97}] * x[{i * 7 % 89}] / (1.0 + x[{i * 13 % 83}] * s);"
            for i in range(statements)]
    return "\n".join(["double f(double *x) {", "  double s = 0.0;", *body, "  return s;", "}"])


@pytest.mark.skipif(not sys.platform.startswith("linux") or shutil.which("gcc") is None,
                    reason="reads /proc; needs gcc")
def test_sigkill_during_a_real_compile_leaves_no_cc1(tmp_path, env):
    """SIGKILL (no cleanup can run) of a process compiling with gcc: the gcc driver died with it
    but cc1 ran on alone for minutes (the parent-death signal reached the driver only). The
    compiler's group leader now kills the whole group."""
    source = tmp_path / "slow.c"
    source.write_text(slow_c_source())
    child = subprocess.Popen(
        [sys.executable, "-c", "import sys; from pathlib import Path; from casadrone.codegen "
         "import compile_source; compile_source('slow', Path(sys.argv[1]).read_text())",
         str(source)], env={**env, "CC": "gcc"}, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 120
        tree = descendants(child.pid)
        while "cc1" not in tree.values():
            assert child.poll() is None and time.monotonic() < deadline, "cc1 never started"
            time.sleep(0.05)
            tree = descendants(child.pid)
    finally:
        child.kill()  # SIGKILL
        child.wait()
    assert {"gcc", "cc1"} <= set(tree.values()), tree
    deadline = time.monotonic() + 5
    while any(alive(p) for p in tree) and time.monotonic() < deadline:
        time.sleep(0.05)
    left = {p: name for p, name in tree.items() if alive(p)}
    for p in left:  # not to leave a compiler running when the test fails
        with contextlib.suppress(ProcessLookupError):
            os.kill(p, signal.SIGKILL)
    assert left == {}, f"the compiler outlived casadrone: {left}"
    assert not list((Path(env["CASADRONE_CACHE"])).glob("slow_*.so"))
