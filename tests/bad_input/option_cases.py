"""Bad options of every ``asa`` command."""

from __future__ import annotations

from tests.bad_input import case

# ------------------------------------------------------------- options of every command


def options(name: str, *argv: str) -> None:
    """``asa`` with these arguments; ``{tmp}`` is replaced by the case's folder."""
    case(f"options-{name}", lambda t, e: [a.replace("{tmp}", str(t)) for a in argv])


options("no-command-unknown", "teleport")
options("top-unknown-option", "--colour")
options("plan-participants-trillion", "plan", "--protocol", "pilot", "--participants", str(10**12))
options("plan-participants-2e63", "plan", "--protocol", "pilot", "--participants", str(2**63 - 1))
options("plan-participants-zero", "plan", "--protocol", "pilot", "--participants", "0")
options("plan-participants-text", "plan", "--protocol", "pilot", "--participants", "ten")
options("plan-seed-10e23", "plan", "--protocol", "pilot", "--seed", str(10**23))
options("plan-seed-negative", "plan", "--protocol", "pilot", "--seed", "-1")
options("plan-seed-2e63", "plan", "--protocol", "pilot", "--seed", str(2**63))
options("plan-protocol-unknown", "plan", "--protocol", "moon")
options(
    "synth-participants-trillion",
    "synth",
    "--protocol",
    "pilot",
    "--db",
    "{tmp}/s.db",
    "--participants",
    str(10**12),
)
options(
    "synth-seed-10e23", "synth", "--protocol", "pilot", "--db", "{tmp}/s.db", "--seed", str(10**23)
)
options(
    "synth-workers-zero", "synth", "--protocol", "pilot", "--db", "{tmp}/s.db", "--workers", "0"
)
options(
    "synth-workers-billion",
    "synth",
    "--protocol",
    "pilot",
    "--db",
    "{tmp}/s.db",
    "--workers",
    str(10**9),
)
options("synth-protocol-missing", "synth", "--db", "{tmp}/s.db")
options("synth-protocol-unknown", "synth", "--protocol", "moon", "--db", "{tmp}/s.db")
options("pilot-participants-zero", "pilot", "--out", "{tmp}/p", "--participants", "0")
options("pilot-participants-big", "pilot", "--out", "{tmp}/p", "--participants", "10001")
options("pilot-seed-negative", "pilot", "--out", "{tmp}/p", "--seed", "-5")
options("pilot-workers-zero", "pilot", "--out", "{tmp}/p", "--workers", "0")
options(
    "run-seed-10e23",
    "run",
    "--protocol",
    "pilot",
    "--participant",
    "P01",
    "--db",
    "{tmp}/r.db",
    "--seed",
    str(10**23),
)
options(
    "run-seed-negative",
    "run",
    "--protocol",
    "pilot",
    "--participant",
    "P01",
    "--db",
    "{tmp}/r.db",
    "--seed",
    "-1",
)
options(
    "run-code-path", "run", "--protocol", "pilot", "--participant", "../P01", "--db", "{tmp}/r.db"
)
options("run-code-empty", "run", "--protocol", "pilot", "--participant", "", "--db", "{tmp}/r.db")
options(
    "run-code-long", "run", "--protocol", "pilot", "--participant", "P" * 65, "--db", "{tmp}/r.db"
)
options(
    "run-input-unknown",
    "run",
    "--protocol",
    "pilot",
    "--participant",
    "P01",
    "--db",
    "{tmp}/r.db",
    "--input",
    "telepathy",
)
options(
    "run-protocol-bad-file",
    "run",
    "--protocol",
    "{tmp}",
    "--participant",
    "P01",
    "--db",
    "{tmp}/r.db",
)
options(
    "demonstrations-runs-zero",
    "demonstrations",
    "record",
    "--task",
    "all",
    "--runs",
    "0",
    "--out",
    "{tmp}/d",
)
options(
    "demonstrations-runs-billion",
    "demonstrations",
    "record",
    "--task",
    "all",
    "--runs",
    str(10**9),
    "--out",
    "{tmp}/d",
)
options(
    "demonstrations-task-unknown",
    "demonstrations",
    "record",
    "--task",
    "juggling",
    "--out",
    "{tmp}/d",
)
options(
    "demonstrations-seed-negative",
    "demonstrations",
    "record",
    "--task",
    "all",
    "--seed",
    "-1",
    "--out",
    "{tmp}/d",
)
options(
    "demonstrations-scene-unknown",
    "demonstrations",
    "record",
    "--task",
    "doorway_crossing",
    "--scene",
    "moon",
    "--out",
    "{tmp}/d",
)
options("train-seed-negative", "train", "--out", "{tmp}/m.npz", "--seed", "-1")
options("train-out-missing", "train")
options("evaluate-folds-one", "evaluate", "--folds", "1", "--quiet")
options("evaluate-repeats-zero", "evaluate", "--repeats", "0", "--quiet")
options("evaluate-workers-zero", "evaluate", "--workers", "0", "--quiet")
options("evaluate-seed-10e23", "evaluate", "--seed", str(10**23), "--quiet")
options("bench-only-unknown", "bench", "--only", "everything")
options("export-out-missing", "export", "--db", "{tmp}/x.db")
options("db-unknown-subcommand", "db", "repair")
options("db-check-db-missing", "db", "check")
options("db-push-to-missing", "db", "push", "--from", "{tmp}/x.db")
options("db-push-from-missing", "db", "push", "--to", "{tmp}/x.db")
options("db-push-from-no-file", "db", "push", "--from", "{tmp}/x.db", "--to", "{tmp}/y.db")
options("db-push-into-itself", "db", "push", "--from", "{tmp}/x.db", "--to", "sqlite:///{tmp}/x.db")
options("scenario-unknown-subcommand", "scenario", "paint")
options("stats-dv-missing", "stats", "--csv", "{tmp}/x.csv", "--within", "m", "--subject", "s")
options("serve-protocol-unknown", "serve", "--protocol", "moon", "--db", "{tmp}/w.db")
options("serve-port-huge", "serve", "--protocol", "pilot", "--db", "{tmp}/w.db", "--port", "70000")
options("serve-code-bad", "serve", "--protocol", "pilot", "--db", "{tmp}/w.db", "--invite", "a b")
options("invite-nothing", "invite", "--db", "{tmp}/w.db")
options("invite-count-huge", "invite", "--db", "{tmp}/w.db", "--count", "100000")
options("invite-code-bad", "invite", "--db", "{tmp}/w.db", "--participant", "../x")
options("snapshots-protocol-unknown", "snapshots", "--protocol", "moon", "--out", "{tmp}/s")
options("run-recordings-a-file", "run", "--protocol", "pilot", "--participant", "P01", "--db",
        "{tmp}/r.db", "--recordings", "{tmp}/r.db")  # fmt: skip
