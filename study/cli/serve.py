"""``asa serve`` and ``asa invite``: sessions for participants who join from a link
(issue 37; :mod:`study.web`)."""

from __future__ import annotations

import secrets
from pathlib import Path

import click

from study.cli import db_option

DEFAULT_PORT = 8080


def _base(host: str, port: int, base_url: str | None) -> str:
    return base_url or f"http://{host}:{port}"


@click.command("serve")
@click.option("--protocol", "protocol", required=True, help="Shipped protocol name or TOML file.")
@db_option("Study database: a SQLite file (created if missing) or a SQLAlchemy URL.")
@click.option(
    "--host",
    default="127.0.0.1",
    show_default=True,
    help="Address to listen on (another than 127.0.0.1 only behind a TLS proxy).",
)
@click.option(
    "--port",
    type=click.IntRange(0, 65535),
    default=DEFAULT_PORT,
    show_default=True,
    help="Port (0: any free port, printed).",
)
@click.option(
    "--recordings",
    type=click.Path(file_okay=False, path_type=Path),
    default=None,
    help="Folder of the recordings [default: <db name>_recordings beside the database].",
)
@click.option(
    "--invite",
    "codes",
    multiple=True,
    help="Make an invite for this participant code and print its link (repeatable).",
)
@click.option(
    "--count",
    type=click.IntRange(0, 1000),
    default=0,
    help="Make this many invites with free codes (W001, ...) and print their links.",
)
@click.option(
    "--base-url",
    default=None,
    help="The address participants use, e.g. "
    "https://study.example.org behind a proxy [default: http://HOST:PORT].",
)
@click.option(
    "--prolific",
    is_flag=True,
    help="Accept Prolific's links: /join?PROLIFIC_PID="
    "...&STUDY_ID=...&SESSION_ID=... (the PROLIFIC_PID is the participant's code).",
)
@click.option(
    "--max-sessions",
    type=click.IntRange(1, 64),
    default=8,
    show_default=True,
    help="Sessions running at once (one process each).",
)
@click.option("--no-camera", is_flag=True, help="No camera image on the page.")
@click.option("--site", default=None, help="The site of every session (a multi-site study).")
def serve(
    protocol: str, db: str, host: str, port: int, recordings: Path | None, codes: tuple[str, ...],
    count: int, base_url: str | None, prolific: bool, max_sessions: int, no_camera: bool,
    site: str | None,
) -> None:  # fmt: skip
    """Run the protocol's sessions for participants who open their link in a browser.

    Each participant's whole session (every phase, as `asa run`) runs in a process of its
    own; the page draws the same screens as the pygame window. Prints the experimenter's
    live view and any invites made; Ctrl-C stops (running sessions are stored aborted and
    resume when their link is opened again).

    \b
    Example:
      asa serve --protocol pilot --db web.db --count 4
      asa invite --db web.db --participant P07       # another link, while it runs
    """
    from study.data.storage import open_database
    from study.engine.protocol import load_protocol
    from study.web import invites
    from study.web.server import ServeOptions
    from study.web.server import serve as run_server

    load_protocol(protocol)  # bad input: one line, before anything listens
    engine = open_database(db)
    try:
        wanted = list(codes) + (invites.free_codes(engine, count) if count else [])
        made = invites.make_invites(engine, wanted) if wanted else []
    finally:
        engine.dispose()
    token = secrets.token_urlsafe(16)
    options = ServeOptions(
        protocol=protocol, db=db, experimenter_token=token,
        recordings=str(recordings.resolve()) if recordings else None, prolific=prolific,
        max_sessions=max_sessions, camera=not no_camera, site=site,
    )  # fmt: skip

    def ready(bound: int) -> None:
        base = _base(host, bound, base_url)
        click.echo(f"asa serve: listening on http://{host}:{bound} (Ctrl-C stops)")
        click.echo(f"experimenter: {base}/experimenter?token={token}")
        for code, t in made:
            click.echo(f"{code}\t{invites.link(base, t)}")

    run_server(options, host=host, port=port, ready=ready)


@click.command("invite")
@db_option("Study database (where `asa serve` runs).")
@click.option("--participant", "codes", multiple=True, help="Participant code (repeatable).")
@click.option(
    "--count",
    type=click.IntRange(0, 10000),
    default=0,
    help="Invites with free codes W001, W002, ...",
)
@click.option(
    "--base-url",
    default=f"http://127.0.0.1:{DEFAULT_PORT}",
    show_default=True,
    help="The address participants use.",
)
@click.option(
    "--out",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="Write the links to this file (readable by you only) instead of printing.",
)
def invite(codes: tuple[str, ...], count: int, db: str, base_url: str, out: Path | None) -> None:
    """Make invites: one link per participant, each with an unguessable token.

    Only the token's SHA-256 is stored, so a lost link cannot be shown again: make another.

    \b
    Example:
      asa invite --db web.db --participant P01 --participant P02
      asa invite --db web.db --count 20 --base-url https://study.example.org --out links.tsv
    """
    from study.data.storage import open_database
    from study.web import invites

    if not codes and not count:
        raise ValueError("invite: give --participant CODE or --count N")
    engine = open_database(db)
    try:
        wanted = list(codes) + (invites.free_codes(engine, count) if count else [])
        made = invites.make_invites(engine, wanted)
    finally:
        engine.dispose()
    if out is not None:
        invites.write_links(out, made, base_url)
        click.echo(f"{out}: {len(made)} links")
        return
    for code, token in made:
        click.echo(f"{code}\t{invites.link(base_url, token)}")


@click.command("snapshots")
@click.option("--protocol", "protocol", required=True, help="Shipped protocol name or TOML file.")
@click.option(
    "--out",
    type=click.Path(file_okay=False, path_type=Path),
    required=True,
    help="Folder for the PNG files (NNNN_<screen>.png).",
)
@click.option("--no-camera", is_flag=True, help="No camera image on the driving screen.")
@click.option(
    "--trial-s",
    type=click.FloatRange(2.0, 600.0),
    default=10.0,
    show_default=True,
    help="Every trial cut to this many seconds (a look at the screens, not data).",
)
def snapshots(protocol: str, out: Path, no_camera: bool, trial_s: float) -> None:
    """Screenshots of every screen of a protocol as the browser shows it.

    A throwaway study on 127.0.0.1, one headless Chromium page (Debian's chromium and
    chromedriver, selenium from the test extra) driven by a scripted person with a faked
    gamepad through the whole session. The pygame window's screens:
    `asa run --input scripted --headless --snapshots DIR`.

    \b
    Example:
      asa snapshots --protocol pilot --out web-shots/
    """
    from study.engine.protocol import load_protocol
    from study.web.testing import snapshot_session

    load_protocol(protocol)
    shots = snapshot_session(protocol, out, camera=not no_camera, trial_s=trial_s)
    click.echo(f"{out}: {len(shots)} screenshots")
