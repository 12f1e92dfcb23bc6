"""The experimenter's side of a session (issue 19): timeouts named as such in the database
and on the terminal, one live status line instead of a scrolling log, Ctrl-C handled by
the session itself (also when SIGINT was ignored, as for a script's ``cmd &``), and after
an interruption the trial cut short and a ``--resume`` command that resumes."""

from __future__ import annotations

import io
import os
import shlex
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from sqlalchemy import select
from sqlalchemy.orm import Session

from analysis.data import load_study, tidy
from analysis.data.frames import FINISHED
from study.cli.terminal import STATUS_EVERY_S, ExperimenterTerminal, resume_command
from study.data.dbtools import check
from study.data.storage import TRIAL_FINISHED, Event, SessionRow, Trial, open_database
from study.engine.clocks import INTERRUPTED, ExperimenterControl, sigint_aborts
from study.engine.launch import run_participant
from study.engine.protocol import load_protocol
from study.engine.session import run_session
from study.participants import ScriptedParticipant

# practice and main trials short enough to time out: the practice goal is not reached in
# 2 s, the main route not in 4 s
PROTOCOL = """
[study]
name = "terminal"
seed = {seed}

[modes]
names = ["manual", "reactive_bn"]

[[phases]]
kind = "briefing"
text = "Test run."

[[phases]]
kind = "training"
scenario = "practice_course"
duration_s = 1.0
secondary = false
direct_view = true

[[phases]]
kind = "practice"
scenario = "practice_course"
time_limit_s = 2.0
max_collisions = 0
secondary = false
max_attempts = 2
on_fail = "continue"

[[phases]]
kind = "main"
scenario = "practice_course"
route = ["A", "B"]
inspection = false
secondary = false
block_size = 3
timeout_s = {timeout_s}

[phases.after_trial]
instrument = "nasa_tlx"
weights = "raw"

[[phases]]
kind = "debrief"
text = "Done."
"""


def _protocol(
    tmp_path: Path, seed: int, timeout_s: float = 4.0, *, without: tuple[str, ...] = ()
) -> Path:
    """The protocol file, leaving out the phases of the kinds ``without``."""
    head, *phases = PROTOCOL.format(seed=seed % 1000, timeout_s=timeout_s).split("[[phases]]\n")
    kept = [p for p in phases if not any(p.startswith(f'kind = "{k}"\n') for k in without)]
    path = tmp_path / "terminal.toml"
    path.write_text("[[phases]]\n".join([head, *kept]), encoding="utf-8")
    return path


def _trials(db: Path) -> list[Trial]:
    engine = open_database(db, create=False)
    with Session(engine) as s:
        rows = list(s.scalars(select(Trial).order_by(Trial.id)))
    engine.dispose()
    return rows


def test_finished_statuses_agree():
    assert FINISHED == TRIAL_FINISHED  # the analysis repeats them to stay light


# ---------------------------------------------------------------------- timeouts


def test_a_timed_out_trial_is_named_so_in_the_database_and_on_the_terminal(tmp_path, seed):
    db = tmp_path / "t.db"
    lines: list[str] = []
    summary = run_session(
        load_protocol(_protocol(tmp_path, seed)),
        "P01",
        db,
        participant=ScriptedParticipant(np.random.default_rng(seed)),
        seed=seed,
        progress=lines.append,
    )
    assert summary.status == "completed"
    trials = _trials(db)
    engine = open_database(db, create=False)
    with Session(engine) as s:
        ended = {
            e.trial_id: e.detail["status"]
            for e in s.scalars(select(Event).where(Event.kind == "trial_ended"))
        }
        timeouts = set(s.scalars(select(Event.trial_id).where(Event.kind == "timeout")))
    engine.dispose()
    for t in trials:
        if t.phase == "training":  # its duration is its planned end, not a limit
            assert t.status == ended[t.id] == "completed"
        elif t.outcome["timed_out"]:
            assert t.status == ended[t.id] == "timed_out" and t.id in timeouts
            assert not t.completed_task
        else:
            assert t.status == ended[t.id] == "completed"
    main = [t for t in trials if t.phase == "main"]
    assert main and all(t.status == "timed_out" for t in main)  # A to B takes > 4 s
    # practice attempts that timed out count as attempts: two per mode, then go on
    practice = [t for t in trials if t.phase == "practice"]
    assert all(t.status in TRIAL_FINISHED for t in practice)
    for ordinal in {t.ordinal for t in practice}:
        tries = [t for t in practice if t.ordinal == ordinal]
        assert len(tries) == (1 if tries[0].outcome.get("passed") else 2)
    main_lines = [line for line in lines if " main #" in line and "NASA" not in line]
    assert len(main_lines) == len(main)
    for line in main_lines:
        assert "timed out at the 4 s limit" in line and "completed" not in line, line
    report = check(db, verify_recordings=False)
    assert report.clean, report.text()
    # the analysis counts them as timed out, and reads a database written before the
    # status existed ("completed" with completed_task false) the same way
    flags = tidy(load_study(db)).trials.set_index("trial_id")["timed_out"]
    assert flags.loc[[t.id for t in main]].all()
    with sqlite3.connect(db) as con:
        con.execute("UPDATE trial SET status = 'completed' WHERE status = 'timed_out'")
    old = tidy(load_study(db)).trials.set_index("trial_id")["timed_out"]
    assert old.sort_index().equals(flags.sort_index())


# ---------------------------------------------------------------------- live status


class _Clock:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


class _Writer:
    def __init__(self, engine, trial_id: int) -> None:
        self.engine, self.trial_id = engine, trial_id


def test_the_status_is_one_live_line_on_a_terminal_and_a_line_every_30_s_in_a_log(tmp_path):
    clock = _Clock()
    out = {tty: io.StringIO() for tty in (True, False)}
    terms = {
        tty: ExperimenterTerminal("P01", stream=out[tty], tty=tty, screen=True, clock=clock)
        for tty in out
    }
    writer = _Writer(open_database(tmp_path / "s.db"), trial_id=-1)
    for term in terms.values():
        term.on_tick(1, writer)
    for k in range(120):  # a 10-minute trial with the screen's status every 5 s
        clock.now = 5.0 * k
        for term in terms.values():
            term.status(f"main: t {5.0 * k:5.1f} s, 0 collisions")
    for term in terms.values():
        term.line("P01 main #0 mode manual: timed out at the 600 s limit")
    writer.engine.dispose()
    log = out[False].getvalue().splitlines()
    assert len(log) - 1 <= 600 / STATUS_EVERY_S and len(log) >= 600 / STATUS_EVERY_S - 1
    assert log[-1].startswith("P01 main #0")
    live = out[True].getvalue()
    assert live.count("\n") == 1  # only the trial's line stays
    assert live.count("\r") >= 120  # the status rewritten in place
    assert live.endswith("\r\x1b[KP01 main #0 mode manual: timed out at the 600 s limit\n")


def test_resume_command_repeats_the_options_with_resume():
    params = {
        "protocol": "pilot",
        "code": "P01",
        "db": Path("my study.db"),
        "input_kind": "human",
        "seed": None,
        "force": False,
        "headless": False,
        "snapshots": None,
        "fast": False,
    }
    assert shlex.split(resume_command(params)) == [
        "asa", "run", "--protocol", "pilot", "--participant", "P01", "--db", "my study.db",
        "--input", "human", "--resume",
    ]  # fmt: skip


# ---------------------------------------------------------------------- Ctrl-C


def test_sigint_handler_is_installed_for_the_run_and_restored_after(tmp_path, seed):
    """Started with SIGINT ignored (a script's ``&``): the session still stops at Ctrl-C,
    storing the running trial as aborted, and the ignoring handler comes back after."""
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    seen: list[object] = []
    try:

        def on_tick(tick: int, writer) -> None:
            seen.append(signal.getsignal(signal.SIGINT))
            if tick == 7 and writer.trial_id >= 3:  # a few ticks into the third trial
                os.kill(os.getpid(), signal.SIGINT)

        summary = run_participant(
            str(_protocol(tmp_path, seed)), "P01", tmp_path / "i.db", seed=seed, on_tick=on_tick
        )
        assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN
    finally:
        signal.signal(signal.SIGINT, previous)
    assert seen and all(callable(h) and h not in (signal.SIG_IGN, previous) for h in seen)
    assert summary.status == "aborted"
    aborted = [t for t in _trials(tmp_path / "i.db") if t.status == "aborted"]
    assert [t.id for t in aborted] == [3]
    assert aborted[0].outcome["aborted_reason"] == INTERRUPTED
    assert aborted[0].outcome["ticks"] == 7  # the tick that ran was stored, no more


def test_sigint_outside_a_trial_raises_and_a_second_one_does_too():
    control = ExperimenterControl()
    before = signal.getsignal(signal.SIGINT)
    with sigint_aborts(control):
        with pytest.raises(KeyboardInterrupt):  # a page or form: stop at once
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(1.0)
        control.ticking = True
        os.kill(os.getpid(), signal.SIGINT)  # in a trial: the loop ends it
        time.sleep(0.05)
        assert control.aborted and control.reason == INTERRUPTED
        with pytest.raises(KeyboardInterrupt):  # the loop does not stop: Ctrl-C again
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(1.0)
    assert signal.getsignal(signal.SIGINT) is before


def _asa(*args: str) -> list[str]:
    return [sys.executable, "-m", "study.cli", *args]


def _running_samples(db: Path) -> int:
    """Samples of a running main trial (0 while none runs or the schema is missing)."""
    if not db.exists():
        return 0
    try:
        with sqlite3.connect(f"file:{db}?mode=ro", uri=True, timeout=5) as con:
            row = con.execute(
                "SELECT count(*) FROM sample JOIN trial ON trial.id = sample.trial_id "
                "WHERE trial.phase = 'main' AND trial.status = 'running'"
            ).fetchone()
        return int(row[0])
    except sqlite3.Error:
        return 0


def test_ctrl_c_of_a_background_run_prints_the_trial_and_a_resume_command_that_works(
    tmp_path, seed
):
    # without the training and practice trials (10 s paced by the wall clock before the
    # first main trial): test_sigint_handler_is_installed_for_the_run_and_restored_after and
    # the timeouts test above run them
    protocol = _protocol(tmp_path, seed, without=("training", "practice"))
    db = tmp_path / "k.db"
    args = ["run", "--protocol", str(protocol), "--participant", "P01", "--db", str(db),
            "--headless", "--seed", str(seed % 10_000)]  # fmt: skip
    env = {**os.environ, "SDL_VIDEODRIVER": "dummy"}
    proc = subprocess.Popen(
        _asa(*args), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN),
    )  # fmt: skip
    try:
        deadline = time.monotonic() + 240
        while _running_samples(db) < 10:  # paced by the wall clock: 20 ticks a second
            assert proc.poll() is None, proc.communicate()
            assert time.monotonic() < deadline
            time.sleep(0.05)
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == 130, out + err
    lines = out.splitlines()
    aborted = next(line for line in lines if " aborted at " in line)
    assert "main #0" in aborted and "mode " in aborted and INTERRUPTED in aborted
    command = lines[lines.index(next(x for x in lines if "to continue it" in x)) + 1]
    words = shlex.split(command)
    assert words[:2] == ["asa", "run"] and words[-1] == "--resume"
    done = subprocess.run(_asa(*words[1:]), capture_output=True, text=True, timeout=300, env=env)
    assert done.returncode == 0, done.stdout + done.stderr
    resumed = done.stdout.splitlines()[0]
    assert "resumed" in resumed and "main #0" in resumed and "runs again as attempt 1" in resumed
    trials = _trials(db)
    first = [t for t in trials if t.phase == "main" and t.ordinal == 0]
    assert [t.status for t in first] == ["aborted", "timed_out"]
    engine = open_database(db, create=False)
    with Session(engine) as s:
        assert s.scalars(select(SessionRow)).one().status == "completed"
    engine.dispose()
    report = check(db)
    assert report.clean, report.text()
