"""Bad CSV files (``asa stats``, ``asa export`` folders), study databases, model files
and demonstration folders."""

from __future__ import annotations

import hashlib
import io
import json
import shutil
import zipfile
from collections.abc import Callable
from pathlib import Path

import numpy as np

from autonomy.model import DEFAULT_MODEL
from tests.bad_input import DEEP, Env, case
from tests.bad_input import write as _write

# --------------------------------------------------------------- asa stats: long CSV

GOOD_CSV = "s,m,y\n1,a,1.0\n1,b,2.0\n2,a,1.5\n2,b,2.5\n3,a,0.5\n3,b,3.0\n"
STATS = ["--dv", "y", "--within", "m", "--subject", "s"]


def stats_csv(name: str, content: str | bytes, *extra: str) -> None:
    def setup(tmp: Path, env: Env) -> list[str]:
        return ["stats", "--csv", str(_write(tmp / "data.csv", content)), *STATS, *extra]

    case(f"stats-{name}", setup)


def stats_value(name: str, value: str) -> None:
    stats_csv(name, GOOD_CSV.replace("1,a,1.0", f"1,a,{value}"))


for _name, _value in [
    ("1e307", "1e307"),
    ("minus-1e300", "-1e300"),
    ("1e16", "1e16"),
    ("inf", "inf"),
    ("minus-inf", "-inf"),
    ("text", "fast"),
    ("1e400", "1e400"),
    ("comma-decimal", '"1,5"'),
    ("hex", "0x10"),
]:
    stats_value(f"value-{_name}", _value)
stats_csv("all-1e307", "s,m,y\n" + "".join(f"{i},{m},1e307\n" for i in range(4) for m in "ab"))
stats_csv("empty-file", "")
stats_csv("header-only", "s,m,y\n")
stats_csv("missing-column", GOOD_CSV.replace("s,m,y", "s,m,z"))
stats_csv("one-level", "s,m,y\n1,a,1\n2,a,2\n3,a,3\n")
stats_csv("empty-subject", GOOD_CSV.replace("2,a,1.5", ",a,1.5"))
stats_csv("extra-field", GOOD_CSV + "4,a,1,oops\n")
stats_csv("latin-1", "s,m,y\n1,caf\xe9,1\n".encode("latin-1"))
stats_csv("binary", bytes(range(256)) * 8)
stats_csv("alpha-zero", GOOD_CSV, "--alpha", "0")
stats_csv("alpha-nan", GOOD_CSV, "--alpha", "nan")
stats_csv("alpha-text", GOOD_CSV, "--alpha", "five")
stats_csv("gate-unknown", GOOD_CSV, "--gate", "never")
case("stats-missing-file", lambda t, e: ["stats", "--csv", str(t / "none.csv"), *STATS])
case("stats-a-directory", lambda t, e: ["stats", "--csv", str(t), *STATS])
case(
    "stats-same-column",
    lambda t, e: (
        ["stats", "--csv", str(_write(t / "d.csv", GOOD_CSV)), "--dv", "y"]
        + ["--within", "y", "--subject", "s"]
    ),
)


# --------------------------------------------- asa report: an export folder (CSV files)


def export_folder(name: str, change: Callable[[Path], None]) -> None:
    """A copy of the fixture study's ``asa export`` folder with ``change`` applied, read
    by ``asa report`` (which stops at the bad file, before any figure)."""

    def setup(tmp: Path, env: Env) -> list[str]:
        folder = tmp / "export"
        shutil.copytree(env.export, folder)
        change(folder)
        return ["report", "--db", str(folder), "--out", str(tmp / "report")]

    case(f"export-{name}", setup)


def _cell(table: str, column: str, value: str, row: int = 0) -> Callable[[Path], None]:
    """Set one cell of ``table``.csv (row ``row`` of the data) to the raw CSV ``value``."""

    def change(folder: Path) -> None:
        import pandas as pd

        path = folder / f"{table}.csv"
        frame = pd.read_csv(path, dtype=str, keep_default_na=False)
        frame.loc[row, column] = value
        frame.to_csv(path, index=False)

    return change


for _table, _column, _value, _row in [
    ("response", "value", "abc", 0),
    ("response", "value", "1e308", 0),
    ("response", "value", "inf", 0),
    ("response", "value", "-1e300", 7),
    ("trial", "completion_time_s", "1e400", 1),
    ("trial", "collisions", "many", 1),
    ("trial", "seed", str(10**30), 0),
    ("participant", "order_index", "first", 0),
    ("participant", "seed", "-inf", 0),
    ("sample", "x", "nan-ish", 0),
    ("sample", "t", "1e309", 0),
    ("question", "answer_time_s", "quick", 0),
    ("study", "seed", "1e99", 0),
    ("participant", "parameters", "{not json", 0),
    ("trial", "outcome", "[unclosed", 1),
    ("study", "protocol_text", "[analysis]\nalpha = 'high'\n", 0),
    ("study", "protocol_text", DEEP, 0),
    ("study", "protocol_text", "[analysis\n", 0),
]:
    export_folder(f"{_table}-{_column}-{_value[:12]}", _cell(_table, _column, _value, _row))
export_folder("response-missing", lambda f: (f / "response.csv").unlink())
export_folder("response-empty", lambda f: (f / "response.csv").write_text(""))
export_folder("trial-binary", lambda f: (f / "trial.csv").write_bytes(bytes(range(256)) * 8))
export_folder("study-no-rows", lambda f: (f / "study.csv").write_text("id,name,seed\n"))
export_folder("sample-no-id", lambda f: (f / "sample.csv").write_text("t,x\n1,2\n"))


# ---------------------------------------------------------------- database files

DB_COMMANDS: dict[str, Callable[[Path, Path], list[str]]] = {
    "db-check": lambda db, t: ["db", "check", "--db", str(db), "--no-verify"],
    "export": lambda db, t: ["export", "--db", str(db), "--out", str(t / "out")],
    "report": lambda db, t: ["report", "--db", str(db), "--out", str(t / "report")],
    "replay": lambda db, t: (
        ["replay", "--db", str(db), "--participant", "P01", "--trial", "1"] + ["--print"]
    ),
}


def _foreign_sqlite(path: Path) -> Path:
    import sqlite3

    with sqlite3.connect(path) as conn:
        conn.execute("CREATE TABLE recipes (id INTEGER PRIMARY KEY, name TEXT)")
    return path


def _truncated(env: Env, path: Path) -> Path:
    path.write_bytes(env.db.read_bytes()[:5000])
    return path


DB_FILES: dict[str, Callable[[Path, Env], Path]] = {
    "empty-file": lambda t, e: _write(t / "x.db", b""),
    "text-file": lambda t, e: _write(t / "x.db", "participant,mode\nP01,manual\n"),
    "random-bytes": lambda t, e: _write(t / "x.db", np.random.default_rng(1).bytes(8192)),
    "foreign-sqlite": lambda t, e: _foreign_sqlite(t / "x.db"),
    "truncated": lambda t, e: _truncated(e, t / "x.db"),
    "a-directory": lambda t, e: t,
    "missing": lambda t, e: t / "none.db",
}

for _file, _make in DB_FILES.items():
    for _command, _argv in DB_COMMANDS.items():
        if _file == "a-directory" and _command == "report":
            continue  # a folder is an export folder to `asa report`: covered above
        case(
            f"database-{_command}-{_file}",
            lambda t, e, make=_make, argv=_argv: argv(make(t, e), t),
        )
for _name, _trial in [("zero", "0"), ("10e30", str(10**30)), ("negative", "-1"), ("text", "one")]:
    case(
        f"replay-trial-{_name}",
        lambda t, e, trial=_trial: (
            ["replay", "--db", str(e.db), "--participant", "P01"] + ["--trial", trial, "--print"]
        ),
    )
case(
    "replay-participant-unknown",
    lambda t, e: ["replay", "--db", str(e.db), "--participant", "Q99", "--trial", "1", "--print"],
)


# --------------------------------------------------------------------- model files


def _npz(path: Path, arrays: dict[str, np.ndarray]) -> Path:
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)
    return _write(path, buffer.getvalue())


def _model_arrays() -> dict[str, np.ndarray]:
    with np.load(DEFAULT_MODEL, allow_pickle=False) as data:
        return {name: data[name] for name in data.files}


def _model_changed(change: Callable[[dict[str, np.ndarray]], None]) -> Callable[[Path], Path]:
    def make(path: Path) -> Path:
        arrays = _model_arrays()
        change(arrays)
        return _npz(path, arrays)

    return make


def _first_float(arrays: dict[str, np.ndarray]) -> str:
    return next(k for k, v in arrays.items() if v.dtype.kind == "f" and v.size)


def _set_nan(arrays: dict[str, np.ndarray]) -> None:
    name = _first_float(arrays)
    arrays[name] = np.full_like(arrays[name], np.nan)


def _reshape(arrays: dict[str, np.ndarray]) -> None:
    name = _first_float(arrays)
    arrays[name] = arrays[name].ravel()[:-1]


def _meta(value: object) -> Callable[[dict[str, np.ndarray]], None]:
    def change(arrays: dict[str, np.ndarray]) -> None:
        arrays["metadata"] = np.array(value if isinstance(value, str) else json.dumps(value))

    return change


MODEL_FILES: dict[str, Callable[[Path], Path]] = {
    "empty-file": lambda p: _write(p, b""),
    "text-file": lambda p: _write(p, "not a model\n"),
    "random-bytes": lambda p: _write(p, np.random.default_rng(2).bytes(4096)),
    "empty-zip": lambda p: _write(p, _empty_zip()),
    "no-metadata": _model_changed(lambda a: a.pop("metadata")),
    "metadata-not-json": _model_changed(_meta("{oops")),
    "metadata-a-list": _model_changed(_meta([1, 2])),
    "format-version-999": _model_changed(_meta({"format_version": 999})),
    "nan-array": _model_changed(_set_nan),
    "wrong-shape": _model_changed(_reshape),
    "truncated": lambda p: _write(p, Path(DEFAULT_MODEL).read_bytes()[:2000]),
    "pickled-object": lambda p: _npz(p, {"metadata": np.array([object()], dtype=object)}),
}


def _empty_zip() -> bytes:
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w"):
        pass
    return buffer.getvalue()


for _name, _make_model in MODEL_FILES.items():
    case(
        f"model-{_name}",
        lambda t, e, make=_make_model: (
            ["evaluate", "--model", str(make(t / "model.npz"))]
            + ["--demonstrations", str(e.demos), "--quiet"]
        ),
    )
case("model-missing", lambda t, e: ["evaluate", "--model", str(t / "no.npz"), "--quiet"])
case("model-a-directory", lambda t, e: ["evaluate", "--model", str(t), "--quiet"])


# --------------------------------------------------------------- demonstration folders


def demos(name: str, change: Callable[[Path], None], command: str = "show") -> None:
    """A copy of the fixture's demonstrations folder with ``change`` applied, read by
    ``asa demonstrations show`` (or ``asa train``)."""

    def setup(tmp: Path, env: Env) -> list[str]:
        folder = tmp / "demos"
        shutil.copytree(env.demos, folder)
        change(folder)
        if command == "train":
            return ["train", "--demonstrations", str(folder), "--out", str(tmp / "m.npz")]
        return ["demonstrations", "show", str(folder)]

    case(f"demonstrations-{command}-{name}", setup)


def _manifest(change: Callable[[dict], object], *, replace: bool = False) -> Callable[[Path], None]:
    """Change the manifest in place, or with ``replace`` write what ``change`` returns."""

    def apply(folder: Path) -> None:
        path = folder / "manifest.json"
        data = json.loads(path.read_text())
        result = change(data)
        path.write_text(json.dumps(result if replace else data))

    return apply


def _run_file(folder: Path) -> Path:
    return next(folder.rglob("*.npz"))


def _rewrite_run(change: Callable[[dict[str, np.ndarray]], None]) -> Callable[[Path], None]:
    """Change the run's arrays and fix the manifest's hash, so the arrays are what is wrong."""

    def apply(folder: Path) -> None:
        path = _run_file(folder)
        with np.load(path, allow_pickle=False) as data:
            arrays = {k: data[k] for k in data.files}
        change(arrays)
        _npz(path, arrays)
        digest = hashlib.sha256(path.read_bytes()).hexdigest()
        _manifest(lambda m: m["runs"][0].update(sha256=digest))(folder)

    return apply


def _nan_q(a: dict[str, np.ndarray]) -> None:
    a["q"] = np.full_like(a["q"], np.nan)


for _command in ("show", "train"):
    demos("no-manifest", lambda f: (f / "manifest.json").unlink(), _command)
    demos("manifest-not-json", lambda f: (f / "manifest.json").write_text("{oops"), _command)
demos("manifest-a-list", _manifest(lambda m: [m], replace=True))
demos("manifest-binary", lambda f: (f / "manifest.json").write_bytes(bytes(range(256))))
demos("version-99", _manifest(lambda m: m.update(version=99)))
demos("runs-not-a-list", _manifest(lambda m: m.update(runs="all")))
demos("run-not-an-object", _manifest(lambda m: m.update(runs=[5])))
demos("run-missing-field", _manifest(lambda m: m["runs"][0].pop("sha256")))
demos("run-unknown-task", _manifest(lambda m: m["runs"][0].update(task="juggling")))
demos("run-file-escapes", _manifest(lambda m: m["runs"][0].update(file="../../etc/passwd")))
demos("run-file-absolute", _manifest(lambda m: m["runs"][0].update(file="/etc/passwd")))
demos("run-ticks-huge", _manifest(lambda m: m["runs"][0].update(ticks=10**30)), "train")
demos("run-file-missing", lambda f: _run_file(f).unlink(), "train")
demos("run-hash-mismatch", lambda f: _run_file(f).write_bytes(b"PK\x05\x06" + b"\0" * 18), "train")
demos("run-nan-array", _rewrite_run(_nan_q), "train")
demos("run-missing-array", _rewrite_run(lambda a: a.pop("u")), "train")
demos("run-truncated-array", _rewrite_run(lambda a: a.update(t=a["t"][:-1])), "train")
case("demonstrations-show-missing", lambda t, e: ["demonstrations", "show", str(t / "none")])
case(
    "demonstrations-show-a-file", lambda t, e: ["demonstrations", "show", str(_write(t / "f", "x"))]
)
