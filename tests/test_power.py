"""``asa power`` end to end on a tiny bank (issue 22): the bank is the same for one and
two Dask workers and after a resume, the outputs are written, bad input is one line and
exit 2, and a bank runs on a separate ``dask scheduler`` / ``dask worker`` pair."""

from __future__ import annotations

import json
import socket
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import pytest

from study.jobs.power import PowerSettings, run_power

TINY = """
# two modes, a short course, three baseline questions: about 2 s of CPU per bank entry
[study]
name = "tiny-power"
participants = 2
seed = 5

[modes]
names = ["manual", "contextual_task"]
counterbalancing = "full_permutation"

[[phases]]
kind = "baseline"
questions = 3

[[phases]]
kind = "main"
scenario = "practice_course"
route = ["A", "B"]
inspection = false
secondary = false
timeout_s = 90.0

[phases.after_trial]
instrument = "nasa_tlx"
weights = "per_trial"

[analysis]
metrics = ["completion_time_s", "collisions", "score_s", "tlx_raw"]
"""

MACHINE = {"cpu_s", "wall_s"}  # the only bank columns that depend on the machine


def _bank(folder: Path) -> dict[str, list[tuple]]:
    """The bank's tables, without the timing columns, in entry order."""
    conn = sqlite3.connect(folder / "bank.sqlite")
    cols = [r[1] for r in conn.execute("PRAGMA table_info(entry)") if r[1] not in MACHINE]
    out = {
        "entry": conn.execute(f"SELECT {', '.join(cols)} FROM entry ORDER BY entry").fetchall(),
        "outcome": conn.execute("SELECT * FROM outcome ORDER BY entry, metric, mode").fetchall(),
    }
    conn.close()
    return out


def _cli(*args: str, timeout: float = 600) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "study.cli", *args], capture_output=True, text=True,
        timeout=timeout,
    )  # fmt: skip


@pytest.fixture
def protocol(tmp_path: Path) -> Path:
    path = tmp_path / "tiny.toml"
    path.write_text(TINY)
    return path


def test_the_bank_is_the_same_for_one_and_two_workers_and_after_a_resume(tmp_path, protocol, seed):
    s = PowerSettings(sizes=(4, 6), studies=20, bank=6, seed=seed % 10_000, workers=1)
    one = run_power(protocol, tmp_path / "one", s)
    two = run_power(protocol, tmp_path / "two", PowerSettings(**{**_fields(s), "workers": 2}))
    bank = _bank(tmp_path / "one")
    assert len(bank["entry"]) == 6 and bank == _bank(tmp_path / "two")
    assert one.result["metrics"] == two.result["metrics"]  # the same studies, the same power
    # orders: entry i drives counterbalancing row i mod 2
    assert [row[2] for row in bank["entry"]] == [0, 1, 0, 1, 0, 1]
    # a bank cut short: entries 1 and 4 lost; --resume drives only those
    conn = sqlite3.connect(tmp_path / "two" / "bank.sqlite")
    with conn:
        conn.execute("DELETE FROM outcome WHERE entry IN (1, 4)")
        conn.execute("DELETE FROM entry WHERE entry IN (1, 4)")
    conn.close()
    with pytest.raises(ValueError, match="--resume"):
        run_power(protocol, tmp_path / "two", PowerSettings(**{**_fields(s), "workers": 2}))
    steps: list[tuple[str, int, int]] = []
    # resumed on one worker: a cluster of two starts and warms up two worker processes at
    # once on this 2-core machine, for the two entries left (the bank was built on two)
    again = run_power(
        protocol, tmp_path / "two", PowerSettings(**{**_fields(s), "resume": True}),
        progress=lambda *step: steps.append(step),
    )  # fmt: skip
    assert _bank(tmp_path / "two") == bank
    assert steps[0] == ("bank", 4, 6) and ("bank", 6, 6) in steps
    assert again.result["metrics"] == one.result["metrics"]
    _outputs(one)


def _fields(s: PowerSettings) -> dict:
    return {f: getattr(s, f) for f in s.__dataclass_fields__}


def _outputs(summary) -> None:
    """power.json, power.html and the curves are written and agree with the result."""
    out = summary.out
    result = json.loads((out / "power.json").read_text())
    assert result["settings"]["sizes"] == [4, 6] and result["bank"]["entries"] == 6
    assert result["bank"]["main_trials"] == 12
    for name in ("power.html", "power_curves.png", "power_curves.svg"):
        assert (out / name).stat().st_size > 0
    metrics = {m["metric"]: m for m in result["metrics"]}
    assert set(metrics) == {"completion_time_s", "collisions", "score_s", "tlx_raw"}
    for m in metrics.values():
        assert [t["test"] for t in m["tests"]] == ["omnibus", "manual vs contextual_task"]
        for t in m["tests"]:
            assert [p["n"] for p in t["curve"]] == [4, 6]
            for p in t["curve"]:
                assert p["studies"] == 20 and p["ci_low"] <= p["power"] <= p["ci_high"]
    assert summary.lines and all(line.split(":")[0] in metrics for line in summary.lines)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--protocol", "no-such-protocol"], "no-such-protocol"),
        (["--sizes", "0,6"], "--sizes: must be integers >= 2"),
        (["--sizes", "six"], "--sizes: must be integers >= 2"),
        (["--sizes", "6,12", "--bank", "10"], "--sizes: N = 12 is larger than the bank"),
        (["--scheduler", "http://x:1"], "--scheduler: 'http://x:1' is not a Dask scheduler"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(tmp_path, protocol, args, message):
    base = ["power", "--protocol", str(protocol), "--out", str(tmp_path / "o")]
    done = _cli(*base, *args)
    assert done.returncode == 2, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and message in lines[0], done.stderr


def test_an_unreachable_scheduler_is_reported_within_seconds(tmp_path, protocol):
    address = f"tcp://127.0.0.1:{_free_port()}"
    start = time.monotonic()
    done = _cli("power", "--protocol", str(protocol), "--out", str(tmp_path / "o"),
                "--bank", "6", "--sizes", "4", "--scheduler", address)  # fmt: skip
    assert time.monotonic() - start < 30
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1, done.stderr
    assert lines[0].startswith(
        f"asa: error: --scheduler: cannot reach a Dask scheduler at {address} within 5 s ("
    )
    assert lines[0].endswith("'dask scheduler' (README, 'Power analysis on a cluster')")


def test_a_bank_on_a_separate_dask_scheduler_and_worker(tmp_path, protocol, seed):
    dask = str(Path(sys.executable).with_name("dask"))
    info = tmp_path / "scheduler.json"
    scheduler = subprocess.Popen(
        [dask, "scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
         "--scheduler-file", str(info)],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
    )  # fmt: skip
    worker = None
    try:
        for _ in range(300):
            if info.exists() and info.read_text().strip():
                break
            time.sleep(0.1)
        address = json.loads(info.read_text())["address"]
        worker = subprocess.Popen(
            [dask, "worker", address, "--nworkers", "1", "--nthreads", "1", "--no-dashboard"],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
        )  # fmt: skip
        out = tmp_path / "remote"
        done = _cli("power", "--protocol", str(protocol), "--out", str(out), "--bank", "4",
                    "--sizes", "4", "--studies", "10", "--seed", str(seed % 10_000),
                    "--scheduler", address)  # fmt: skip
        assert done.returncode == 0, done.stderr
        result = json.loads((out / "power.json").read_text())
        assert result["settings"]["engine"].startswith(address)
        assert result["bank"]["entries"] == 4 and (out / "power.html").exists()
        assert "completion_time_s:" in done.stdout
    finally:
        for proc in (worker, scheduler):
            if proc is not None:
                proc.terminate()
                proc.wait(timeout=30)
