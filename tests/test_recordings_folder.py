"""The recordings' folder is a setting (issue 37): `asa run --recordings DIR` writes there,
and `asa db check` and `asa replay` find them there with `--recordings`, also after the
folder was moved; `db check` says where it looked."""

from __future__ import annotations

import shutil

from tests.cli_helpers import asa
from tests.mini_protocol import mini_protocol


def test_recordings_in_a_folder_of_their_own_are_found_where_told(tmp_path, capsys, seed):
    protocol = tmp_path / "mini.toml"
    protocol.write_text(mini_protocol(seed=seed % 1000, timeout_s=1.0))
    db, rec = tmp_path / "s.db", tmp_path / "elsewhere" / "rec"
    code, _, err = asa(capsys, "run", "--protocol", protocol, "--participant", "P01",
                       "--db", db, "--recordings", rec)  # fmt: skip
    assert code == 0, err
    assert list(rec.glob("P01/*.rrd"))
    code, out, _ = asa(capsys, "db", "check", "--db", db, "--no-verify")
    assert code == 0 and f"recordings: looked in {tmp_path}" in out
    moved = tmp_path / "archive"
    shutil.move(rec, moved)
    code, out, _ = asa(capsys, "db", "check", "--db", db, "--no-verify")
    assert code == 1 and "is missing" in out
    code, out, _ = asa(capsys, "db", "check", "--db", db, "--no-verify", "--recordings", moved)
    assert code == 0 and f"recordings: looked in {moved}" in out
    code, out, err = asa(capsys, "replay", "--db", db, "--participant", "P01", "--trial", 1,
                         "--print", "--recordings", moved)  # fmt: skip
    assert code == 0, err
