"""The modal driver of long operators, with a stand-in window manager (modal operators get no
timer events headless): progress is shown, Esc cancels before anything is written and runs the
job's clean-up, errors become reports."""

import importlib
import warnings
from types import SimpleNamespace

import pytest

pytest.importorskip("bpy")


class FakeWindowManager:
    def __init__(self):
        self.progress, self.timers, self.handlers = [], 0, 0

    def progress_begin(self, low, high):
        self.progress.append("begin")

    def progress_update(self, value):
        self.progress.append(value)

    def progress_end(self):
        self.progress.append("end")

    def event_timer_add(self, interval, window=None):
        self.timers += 1
        return "timer"

    def event_timer_remove(self, timer):
        self.timers -= 1

    def modal_handler_add(self, operator):
        self.handlers += 1


def make_job(extension, log, fail_with=None, warn=None):
    base = extension.operators.base

    class Job(base.GeneratorOperator):
        def report(self, kind, message):
            log.append((set(kind), message))

        def run(self, context):
            try:
                log.append("validated")
                yield 0.0
                yield 0.5
                if warn:
                    warnings.warn(warn)
                if fail_with:
                    raise fail_with
                log.append("wrote")
                self.summary = "done"
            finally:
                log.append("cleaned up")

    return Job()


def event(kind):
    return SimpleNamespace(type=kind)


#: Seconds a planted core call lasts at most: it ends earlier when the test lets it go, and only a
#: defect (a tick or Esc waiting for the call) makes it last this long, so no machine is that slow.
CALL_SECONDS = 600


def start(extension, log, **options):
    job = make_job(extension, log, **options)
    window_manager = FakeWindowManager()
    context = SimpleNamespace(window_manager=window_manager, window=object())
    assert job._start_modal(context) == {'RUNNING_MODAL'}
    assert log == ["validated"] and window_manager.handlers == 1
    return job, context, window_manager


def test_timer_runs_the_job_with_progress(extension):
    log = []
    job, context, window_manager = start(extension, log)
    assert job.modal(context, event('MOUSEMOVE')) == {'RUNNING_MODAL'}
    statuses = [job.modal(context, event('TIMER')) for _ in range(2)]
    assert statuses == [{'RUNNING_MODAL'}, {'FINISHED'}]
    assert log == ["validated", "wrote", "cleaned up", ({'INFO'}, "done")]
    assert window_manager.progress == ["begin", 50, 100, "end"]
    assert window_manager.timers == 0


def test_escape_cancels_before_anything_is_written(extension):
    log = []
    job, context, window_manager = start(extension, log)
    job.modal(context, event('TIMER'))
    assert job.modal(context, event('ESC')) == {'CANCELLED'}
    assert "wrote" not in log and "cleaned up" in log
    assert ({'WARNING'}, "Cancelled: nothing was changed") in log
    assert window_manager.progress[-1] == "end" and window_manager.timers == 0


def test_expected_errors_become_reports(extension):
    log = []
    error = extension.operators.base.InputError("Pick two keys")
    job, context, _window_manager = start(extension, log, fail_with=error)
    statuses = [job.modal(context, event('TIMER')) for _ in range(2)]
    assert statuses[-1] == {'CANCELLED'}
    assert ({'ERROR'}, "Pick two keys") in log and "wrote" not in log


def test_unexpected_error_still_ends_the_modal(extension):
    """A bug in a step propagates, but the timer and the progress cursor go first."""
    log = []
    job, context, window_manager = start(extension, log, fail_with=ZeroDivisionError("bug"))
    job.modal(context, event('TIMER'))
    with pytest.raises(ZeroDivisionError):
        job.modal(context, event('TIMER'))
    assert window_manager.progress[-1] == "end" and window_manager.timers == 0
    assert "cleaned up" in log and "wrote" not in log


def test_core_warnings_become_warning_reports(extension, core):
    log = []
    warning = core.ShapeDifferenceWarning("Used the fallback")
    job = make_job(extension, log, warn=warning)
    assert job.execute(SimpleNamespace()) == {'FINISHED'}
    # the summary, then a last line at WARNING: the status bar shows only the last report
    assert log[-3:] == [({'WARNING'}, "Used the fallback"), ({'INFO'}, "done"),
                        ({'WARNING'}, "1 warning, each printed above; look first at: Used the fallback")]


def test_where_the_warnings_are_is_said_for_a_window_and_for_blender_b(extension, core, monkeypatch, capsys):
    """The run's last line and a summary of warnings alike point where the warnings are: headless
    (``blender -b``, these tests) at the log, which has no Info editor or system console to open
    (they said "each in the Info editor" there too); with Blender's UI at the Info editor and the
    system console."""
    base = extension.operators.base
    said = {str(warning): warning for warning in (
        core.sequence_warnings.said_warning(f"between frame {a} and frame {a + 8}, the in-between at factor 0.5: "
                                            "1 triangle(s) flipped or collapsed", "pose", 1,
                                            (f"frame {a}", f"frame {a + 8}"), (0.5,)) for a in (1, 9))}
    headless = (base.look_first(list(said), said), base.summarized(list(said), "Job", said))
    monkeypatch.setattr(base, "bpy", SimpleNamespace(app=SimpleNamespace(background=False)))
    window = (base.look_first(list(said), said), base.summarized(list(said), "Job", said))
    assert headless[0].startswith("2 warnings, each printed above; look first at: between frame 1 and frame 9")
    assert window[0] == headless[0].replace("each printed above", "each in the Info editor")
    assert headless[1][0].endswith("(factor 0.5); each in full on stderr).")
    assert window[1] == [headless[1][0].replace("on stderr", "in the system console")]
    assert capsys.readouterr().err.count(list(said)[1]) == 2  # printed in full by both


def test_warnings_alike_but_for_their_numbers_are_reported_once(extension, core, capsys):
    """The same problem in every gap of a retime, or at every in-between of two keys (each one
    :meth:`core.Interpolator.pose` call), is one warning report with how many more there are, the
    others on the console; a different problem is reported on its own."""
    log = []
    said = [core.sequence_warnings.said_warning(f"between frame {a} and frame {a + 8}, the in-between at factor 0.5: "
                                                f"{n} triangle(s) flipped or collapsed", "pose", 0,
                                                (f"frame {a}", f"frame {a + 8}"), (0.5,)) for a, n in ((1, 3), (9, 12), (17, 1))]
    messages = [str(warning) for warning in said]
    other = "Shape-difference interpolation: 1 piece(s) of the mesh are the mirror image of themselves."

    class Job(extension.operators.base.GeneratorOperator):
        def report(self, kind, message):
            log.append((set(kind), message))

        def run(self, context):
            yield 0.0
            for warning in said + [core.ShapeDifferenceWarning(other)]:
                warnings.warn(warning)
            self.summary = "done"

    assert Job().execute(SimpleNamespace()) == {'FINISHED'}
    reports = [message for kind, message in log if kind == {'WARNING'}]
    assert reports[:-1] == [messages[0][:-1] + " (and 2 more like it; between frame 9 and frame 17 (factor 0.5); "
                            "between frame 17 and frame 25 (factor 0.5); each in full on stderr).", other], reports
    assert reports[-1] == "2 warnings, each printed above; look first at: between frame 1 and frame 9, the " \
        "in-between at factor 0.5", reports
    console = capsys.readouterr().err
    assert messages[1] in console and messages[2] in console and messages[0] not in console
    # two keys' in-betweens, one Interpolator.pose call each: their gap once, with the factors
    pair = {str(warning): warning for warning in (
        core.sequence_warnings.said_warning(f"between shape key 'A' and shape key 'B', the in-between at factor {f}: "
                                            f"{n} triangle(s) flipped or collapsed", "pose", 0,
                                            ("shape key 'A'", "shape key 'B'"), (f,))
        for f, n in ((0.2, 1), (0.4, 5), (0.6, 2), (0.8, 1)))}
    assert extension.operators.base.summarized(list(pair), "In-between", pair) == [
        list(pair)[0][:-1] + " (and 3 more like it; between shape key 'A' and shape key 'B' (factors 0.4, 0.6, 0.8); "
        "each in full on stderr)."]


def test_the_last_line_says_where_the_warnings_are(extension):
    """The run's last line says where its warnings are: in the Info editor from the UI; headless
    (``blender -b``, as the bpy module runs here) there is no Info editor, and Blender prints a
    script's operator reports on the console in order, this line last."""
    look_first = extension.operators.base.look_first
    assert look_first(["Mind the gap: 3 flipped"], headless=False) == \
        "1 warning, each in the Info editor; look first at: Mind the gap"
    assert look_first(["Mind the gap: 3 flipped", "Other"], headless=True) == \
        "2 warnings, each printed above; look first at: Mind the gap"
    assert look_first(["Other"]) == look_first(["Other"], headless=True)


def test_a_summary_of_warnings_alike_reports_the_gap_that_keeps_the_most_flipped_triangles(extension, core, capsys):
    """Of warnings alike, the report line gives in full the one whose in-between keeps the most
    flipped or collapsed triangles (its warning's ``defects``: the gap an artist fixes first, not
    merely the first gap), the others named after it and printed on the console."""
    log = []
    said = [core.sequence_warnings.said_warning(f"between frame {a} and frame {a + 8}, the in-between at factor 0.5: "
                                                f"{n} triangle(s) flipped or collapsed", "pose", kept,
                                                (f"frame {a}", f"frame {a + 8}"), (0.5,))
            for a, n, kept in ((1, 3, 1), (9, 12, 9), (17, 1, 1))]
    messages = [str(warning) for warning in said]

    class Job(extension.operators.base.GeneratorOperator):
        def report(self, kind, message):
            log.append((set(kind), message))

        def run(self, context):
            yield 0.0
            for warning in said:
                warnings.warn(warning)
            self.summary = "done"

    assert Job().execute(SimpleNamespace()) == {'FINISHED'}
    reports = [message for kind, message in log if kind == {'WARNING'}]
    assert reports[:-1] == [messages[1][:-1] + " (and 2 more like it; between frame 1 and frame 9 (factor 0.5); "
                            "between frame 17 and frame 25 (factor 0.5); each in full on stderr)."], reports
    # the run's last line, which the status bar shows, points at the gap that keeps the most
    assert log[-1] == ({'WARNING'}, "1 warning, each printed above; look first at: between frame 9 and frame 17, "
                                    "9 flipped or collapsed triangle(s) kept [pose]"), log
    console = capsys.readouterr().err
    assert messages[0] in console and messages[2] in console and messages[1] not in console


def test_a_problem_said_for_one_in_between_and_for_several_is_one_report_naming_each_gap_in_full(
        extension, core, monkeypatch, capsys):
    """A problem of one in-between in some gaps (``pose``) and of several in another (``poses``)
    is one report, not one per wording, and the gaps it names are the keys' names in full, also
    where a name holds a comma (shape keys named "Key 1, left"): the core's warnings carry their
    gap's key names. Forced through a real sequence: its fits give NaN at one vertex (the safety
    net's warning, as in tests/core/test_inbetween_numerical_failures.py)."""
    import numpy as np

    sequence_inbetweens = importlib.import_module(f"{core.__name__}.sequence_inbetweens")
    solve = sequence_inbetweens.gap_poses

    def poisoned(segment, factors, *ahead):
        solved = solve(segment, factors, *ahead)
        for x, _ in solved:
            x[3] = np.nan
        return solved

    monkeypatch.setattr(sequence_inbetweens, "gap_poses", poisoned)
    u, v = np.meshgrid(np.linspace(0.0, 1.0, 6), np.linspace(0.0, 1.0, 6))
    rest = np.c_[u.ravel(), v.ravel(), np.zeros(36)]
    cells = [6 * j + i for j in range(5) for i in range(5)]
    triangles = np.array([t for c in cells for t in ((c, c + 1, c + 7), (c, c + 7, c + 6))])
    keys = [rest + np.c_[np.zeros((36, 2)), bend * (rest[:, 0] - 0.5) ** 2] for bend in (0.0, 0.3, 0.6, 0.9)]
    names = [f"Key {k}, left" for k in range(1, 5)]
    log = []

    class Job(extension.operators.base.GeneratorOperator):
        def report(self, kind, message):
            log.append((set(kind), message))

        def run(self, context):
            yield 0.0
            sequence = core.SequenceInterpolator(keys, triangles, key_names=names)
            sequence.pose(0, 0.5)
            sequence.pose(1, 0.5)
            sequence.poses(2, [0.25, 0.5, 0.75])
            self.summary = "done"

    assert Job().execute(SimpleNamespace()) == {'FINISHED'}
    reports = [message for kind, message in log if kind == {'WARNING'} and "non-finite" in message]
    assert len(reports) == 1, reports
    assert reports[0].startswith("Shape-difference interpolation: between Key 1, left and Key 2, left, the "
                                 "in-between at factor 0.5: "), reports
    assert reports[0].endswith(" (and 2 more like it; between Key 2, left and Key 3, left (factor 0.5); between "
                               "Key 3, left and Key 4, left; each in full on stderr)."), reports
    assert "between Key 3, left and Key 4, left, 3 of the 3 in-betweens alike" in capsys.readouterr().err


def test_escape_is_answered_while_a_core_call_runs(extension):
    """A core call that takes as long as it likes runs in the worker thread: each timer tick returns
    while it runs and Esc cancels at once, writing nothing. The call runs until the test lets it
    go, after Esc was answered: a tick or an Esc that waited for it would see it end first (it ends
    by itself after ``CALL_SECONDS``, the longest such a wait may take), however slow the machine."""
    import threading
    base = extension.operators.base
    log, started, released, ended = [], threading.Event(), threading.Event(), []

    def core_call():  # stands for a core call of many seconds
        started.set()
        ended.append(released.wait(CALL_SECONDS))
        return "computed"

    class SlowJob(base.GeneratorOperator):
        def report(self, kind, message):
            log.append((set(kind), message))

        def run(self, context):
            yield 0.0
            result = yield from self.compute(0.3, core_call)
            log.append(("wrote", result))

    job, window_manager = SlowJob(), FakeWindowManager()
    context = SimpleNamespace(window_manager=window_manager, window=object())
    try:
        assert job._start_modal(context) == {'RUNNING_MODAL'}
        for _ in range(3):
            assert job.modal(context, event('TIMER')) == {'RUNNING_MODAL'}
        assert started.wait(CALL_SECONDS) and not ended  # the ticks came back while the call runs
        assert job.modal(context, event('ESC')) == {'CANCELLED'}
        assert not ended  # Esc was answered while the call runs
    finally:
        released.set()  # the worker thread is free for the next test
    assert not any(entry[0] == "wrote" for entry in log)
    assert window_manager.progress[-2:] == [30, "end"] and window_manager.timers == 0


def test_headless_runs_say_what_they_work_on_inside_a_long_core_call(extension, core, monkeypatch, capsys):
    """Headless (``blender -b``, these tests) one core call can take many seconds (preparing the
    keys of a 100k mesh) and printed nothing in that time: while it runs, a line
    ``<label>: working on <what>, T s`` comes whenever no line came for ``HEARTBEAT_SECONDS`` (0.05 s
    here; the planted slow call lasts until three such lines came, however slow the machine),
    whole lines, seconds counted from the run's start (the k-th line at least k intervals after
    it, none later than the run's end) and never going back; the call's result is the job's; none
    comes after the call, nor during the quick call after it (its interval set to 30 s by the slow
    call: at 0.05 s a loaded machine's pause between the calls is a silence worth a line)."""
    import re
    import threading
    import time
    base, heartbeat = extension.operators.base, importlib.import_module(f"{core.__name__}.heartbeat")
    results, beats_seen, three_beats = [], [], threading.Event()
    line = heartbeat.line

    def counted(text):  # the heartbeat's thread prints through it
        line(text)
        if text.startswith("Slow Job: working on "):
            beats_seen.append(text)
            if len(beats_seen) >= 3:
                three_beats.set()

    def prepare():  # stands for preparing the keys: lasts until three heartbeat lines came
        waited = three_beats.wait(CALL_SECONDS)
        monkeypatch.setattr(heartbeat, "HEARTBEAT_SECONDS", 30.0)  # the next call's heartbeat
        return "prepared" if waited else "no heartbeat"

    class SlowJob(base.GeneratorOperator):
        bl_label = "Slow Job"

        def report(self, kind, message):
            pass

        def run(self, context):
            yield 0.0
            results.append((yield from self.compute(0.3, prepare, doing="preparing the 3 keys")))
            results.append((yield from self.compute(0.6, max, 1, 2)))

    monkeypatch.setattr(base, "CONSOLE_PROGRESS_INTERVAL", 1e9)  # the first step's line, no other
    monkeypatch.setattr(heartbeat, "HEARTBEAT_SECONDS", 0.05)
    monkeypatch.setattr(heartbeat, "line", counted)
    began = time.monotonic()
    assert SlowJob().execute(SimpleNamespace()) == {'FINISHED'}
    elapsed = time.monotonic() - began
    lines = capsys.readouterr().err.splitlines()
    assert results == ["prepared", 2] and lines[0] == "Slow Job: 0%" and lines[-1] == "Slow Job: done", lines
    beats = [line for line in lines if line.startswith("Slow Job: working on ")]
    assert len(beats) >= 3 and all(re.fullmatch(r"Slow Job: working on preparing the 3 keys, \d+\.\d s", line)
                                   for line in beats), lines
    seconds = [float(line.rsplit(", ", 1)[1][:-2]) for line in beats]
    slack = 0.05 + 1e-9  # printed to 0.1 s: up to 0.05 either way, and the floats' round-off
    assert seconds == sorted(seconds) and len(beats) * 0.05 - slack <= seconds[-1] <= elapsed + slack, (beats, elapsed)
    # all while the slow call runs: right after its step's first line, the quick call and the end after them
    assert lines[1:1 + len(beats)] == beats and lines[1 + len(beats):] == ["Slow Job: done"], lines

    monkeypatch.setattr(heartbeat, "HEARTBEAT_SECONDS", 30.0)  # far above both calls, now quick (three lines came)
    assert SlowJob().execute(SimpleNamespace()) == {'FINISHED'}
    assert not [line for line in capsys.readouterr().err.splitlines() if "working on" in line]


def test_other_warnings_are_passed_on_once(extension, core):
    """A warning that is not the core's (e.g. NumPy's RuntimeWarning) is passed on once to the
    usual warning display (it used to be re-recorded forever), and the job finishes."""
    log = []
    job = make_job(extension, log, warn=RuntimeWarning("Mean of empty slice"))
    with pytest.warns(RuntimeWarning, match="Mean of empty slice") as shown:
        assert job.execute(SimpleNamespace()) == {'FINISHED'}
    assert len(shown) == 1
    assert log[-1] == ({'INFO'}, "done")


def test_the_last_line_names_the_warning_farthest_past_its_allowance(extension, core):
    """Where no warning keeps flipped triangles, the run's last line names the warning farthest past
    what it allows (its ``excess``: a gap's fit 6.7 % off the interpolated metric where 2.1 % is
    allowed, against one 0.8 % off where 0.7 % is), not merely the first; of two such warnings
    alike, the one reported in full is that one too. Without an excess, the first warning."""
    base = extension.operators.base
    said = {str(warning): warning for warning in (
        core.sequence_warnings.said_warning(f"between frame {a} and frame {a + 8}, 7 of the 7 in-betweens, the worst at "
                                            f"factor 0.5: its edges are {off} % shorter", "fit", 0,
                                            (f"frame {a}", f"frame {a + 8}"), (0.5,), off / allowed)
        for a, off, allowed in ((1, 0.8, 0.7), (25, 6.7, 2.1)))}
    assert base.look_first(list(said), said, headless=True) == \
        "2 warnings, each printed above; look first at: between frame 25 and frame 33, 7 of the 7 in-betweens, " \
        "the worst at factor 0.5"
    assert base.summarized(list(said), "Job", said)[0].startswith("Shape-difference interpolation: between frame 25")
    for warning in said.values():
        warning.excess = 0.0
    assert base.look_first(list(said), said, headless=True).endswith("look first at: between frame 1 and frame 9, 7 "
                                                                     "of the 7 in-betweens, the worst at factor 0.5")


def test_the_last_line_and_the_summary_pick_the_same_warning_on_a_tie_of_triangles(extension, core):
    """Of two warnings alike that keep as many flipped triangles, the one reported in full
    (``summarized``: the one farthest past its allowance) is the one the run's last line names
    (``look_first``), whichever comes first."""
    base = extension.operators.base
    said = {str(warning): warning for warning in (
        core.sequence_warnings.said_warning(f"between frame {a} and frame {a + 8}, 7 of the 7 in-betweens, the worst at "
                                            f"factor 0.5: its edges are {off} % shorter", "fit", 3,
                                            (f"frame {a}", f"frame {a + 8}"), (0.5,), off / 2.1)
        for a, off in ((1, 2.5), (25, 6.7)))}
    assert base.summarized(list(said), "Job", said)[0].startswith("Shape-difference interpolation: between frame 25")
    assert base.look_first(list(said), said, headless=True).endswith("look first at: between frame 25 and frame 33, "
                                                                     "3 flipped or collapsed triangle(s) kept [fit]")


def test_escape_stops_the_in_betweens_work_in_the_background(extension, core, monkeypatch):
    """Esc stops what the in-betweens run beside the job's own thread: the gaps a second process holds
    and the calls begun ahead in the pool (core.gap_processes.stop), once, when Esc comes."""
    gap_processes = importlib.import_module(f"{core.__name__}.gap_processes")
    stopped = []
    monkeypatch.setattr(gap_processes, "stop", lambda: stopped.append("stopped"))
    log = []
    job, context, _window_manager = start(extension, log)
    job.modal(context, event('TIMER'))
    assert stopped == []
    assert job.modal(context, event('ESC')) == {'CANCELLED'}
    assert stopped == ["stopped"] and "wrote" not in log
