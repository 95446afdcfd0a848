"""casadrone.progress: the library emits, the caller's listener decides where lines go; nothing
is printed without one except a compile, and ``-q``'s listener drops even that."""

from __future__ import annotations

import io
import re

from casadrone import progress
from casadrone.progress import Event, emit, listening, nested, printer


def test_without_a_listener_only_a_compile_reaches_stderr(capsys):
    emit("start", "start closed-loop: lap 3.9 s")
    emit("compile", "compiling limit_jac (4383 kB of C)")
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err == "casadrone: compiling limit_jac (4383 kB of C)\n"


def test_a_listener_gets_every_event_with_its_depth_and_numbers(capsys):
    seen: list[Event] = []
    with listening(seen.append):
        emit("start", "outer", lap_s=3.9)
        with nested():
            emit("start", "inner")
            with nested():
                emit("compile", "deep compile")
        emit("round", "outer again")
    assert [(e.topic, e.text, e.depth) for e in seen] == [
        ("start", "outer", 0), ("start", "inner", 1), ("compile", "deep compile", 2),
        ("round", "outer again", 0)]
    assert seen[0].values == {"lap_s": 3.9}
    assert capsys.readouterr().err == ""  # the listener had the compile, not stderr
    assert not progress.active()  # restored after the block


def test_quiet_drops_everything_compiles_included(capsys):
    with listening(None):
        emit("compile", "compiling limit_jac")
        emit("start", "start closed-loop")
    assert capsys.readouterr().err == ""


def test_the_printer_shows_the_outermost_call_and_every_compile_with_cpu_and_wall():
    stream = io.StringIO()
    with listening(printer("limit-lap", stream)):
        emit("start", "start closed-loop on 40 intervals: lap 3.9421 s")
        with nested():
            emit("start", "start closed-loop on 30 intervals: an inner lap")
            emit("compile", "compiling limit_jac")
    lines = stream.getvalue().splitlines()
    assert len(lines) == 2
    pattern = r"^limit-lap: {} \[CPU \d+\.\d s, wall \d+\.\d s\]$"
    assert re.match(pattern.format(re.escape("start closed-loop on 40 intervals: lap 3.9421 s")),
                    lines[0])
    assert re.match(pattern.format("compiling limit_jac"), lines[1])


def test_the_printer_counts_cpu_from_its_creation():
    """The CPU in a line is what the command spent since the printer was made: burn a known
    amount of CPU between two events and the second line's figure grows by at least that."""
    import time

    stream = io.StringIO()
    with listening(printer("x", stream)):
        emit("stage", "one")
        c0 = time.process_time()
        while time.process_time() - c0 < 0.3:
            pass
        emit("stage", "two")
    cpu = [float(m) for m in re.findall(r"CPU (\d+\.\d) s", stream.getvalue())]
    assert cpu[1] - cpu[0] >= 0.25


def test_silence_drops_the_events_of_this_process(capsys):
    before = progress._listener
    try:
        progress.silence()
        emit("compile", "compiling limit_jac")
        assert capsys.readouterr().err == ""
    finally:
        progress._listener = before


def test_the_fallback_start_is_reported_by_its_own_name_with_its_inner_lap_nested():
    """casadrone.limit.events.solved: the fallback start's reference lap (a whole limit lap of
    SY250) emits one level deeper; the start itself is reported at the caller's depth under the
    name the solve returns (the result's start name), with its lap and iterations."""
    import numpy as np

    from casadrone.limit import events
    from casadrone.limit.nlp import NlpPoint, NlpSolution

    sol = NlpSolution(True, "Solve_Succeeded", 3.8795, NlpPoint(*(np.zeros(1),) * 4), 61, 0.5)

    def fallback():
        emit("start", "start closed-loop on 40 intervals: the reference's own lap")
        return "reference-SY250", sol

    seen: list[Event] = []
    with listening(seen.append):
        assert events.solved(40, fallback) == ("reference-SY250", sol)
        assert events.solved(40, lambda: None) is None  # no fallback: nothing reported
    assert [(e.depth, e.text.split(":")[0]) for e in seen] == [
        (1, "start closed-loop on 40 intervals"), (0, "start reference-SY250 on 40 intervals")]
    assert seen[1].values["lap_s"] == 3.8795 and seen[1].values["iterations"] == 61
    assert "lap 3.8795 s, 61 iterations" in seen[1].text


def test_counting_adds_live_workers_cpu_to_the_commands_cpu_only_inside_the_block():
    """A pool's live workers are not children this process has waited for: inside
    ``counting`` their CPU (here a declared 100 s) is part of cpu_seconds, after it not."""
    from casadrone.progress import counting, cpu_seconds

    before = cpu_seconds()
    with counting(lambda: 100.0):
        inside = cpu_seconds()
    after = cpu_seconds()
    # the clock's tick is 10 ms and its sums are floats: 532.34 - 432.34 is 99.99999999999994
    assert 100.0 - 1e-9 <= inside - before < 100.5
    assert -1e-9 <= after - before < 0.5
