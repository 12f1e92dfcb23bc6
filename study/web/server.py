"""``asa serve``: the study server (issue 37; DESIGN.md, "Participants in a browser"). One
aiohttp application in one asyncio loop: the participant's page (``/s/<token>``) and its
WebSocket (``/ws/<token>``), Prolific's links (``/join``, with ``prolific``), the static
page's files, and the experimenter's live view (``/experimenter?token=...``) with its
WebSocket. Each participant's session runs in a process of its own (:mod:`.relay`,
:mod:`.session_proc`). A token opens its own session and nothing else; an unknown token
gets the same 404 as a malformed one.
"""

from __future__ import annotations

import asyncio
import contextlib
import hmac
import json
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from aiohttp import WSMsgType, web
from sqlalchemy import select
from sqlalchemy.engine import Engine
from sqlalchemy.orm import Session

from study.data.storage import Participant, Trial, open_database
from study.web import invites
from study.web.relay import SessionHandle
from study.web.session_proc import SessionJob

STATIC = Path(__file__).with_name("static")
MAX_WS_MESSAGE = 65536  # [bytes] beyond this aiohttp closes the page's connection
NOT_FOUND = "This link is not valid. Please check that you copied all of it."
STATUS_EVERY_S = 1.0  # [s] the experimenter's view is updated this often
HEADERS = {  # the page talks to this server only
    "Content-Security-Policy": "default-src 'self'; img-src 'self' blob: data:; "
    "connect-src 'self'; style-src 'self'; script-src 'self'",
    "X-Content-Type-Options": "nosniff",
    "Referrer-Policy": "no-referrer",
    "Cache-Control": "no-store",
}


@dataclass(frozen=True, slots=True)
class ServeOptions:
    """What ``asa serve`` was told."""

    protocol: str
    db: str
    experimenter_token: str
    recordings: str | None = None
    prolific: bool = False  # accept Prolific's links (/join)
    max_sessions: int = 8  # sessions running at once
    camera: bool = True
    site: str | None = None


class StudyServer:
    """The application's state: options, the database engine, the sessions by token."""

    def __init__(self, options: ServeOptions) -> None:
        self.options = options
        self.engine: Engine = open_database(options.db)
        self.sessions: dict[str, SessionHandle] = {}  # invite token's SHA-256 -> session
        self.refused: dict[str, int] = {"bad_token": 0, "full": 0}

    def app(self) -> web.Application:
        app = web.Application(client_max_size=4096)
        app.add_routes([
            web.get("/", self.home),
            web.get("/s/{token}", self.page),
            web.get("/ws/{token}", self.participant_ws),
            web.get("/join", self.join),
            web.get("/experimenter", self.experimenter),
            web.get("/ws-experimenter", self.experimenter_ws),
            web.static("/static", STATIC, follow_symlinks=False),
        ])  # fmt: skip
        app.on_shutdown.append(self._shutdown)
        return app

    # -------------------------------------------------------------- pages

    async def _invite(self, token: str) -> invites.InviteInfo | None:
        loop = asyncio.get_running_loop()
        found = await loop.run_in_executor(None, invites.find, self.engine, token)
        if found is None:
            self.refused["bad_token"] += 1
        return found

    async def home(self, request: web.Request) -> web.Response:
        return _html("<p>Please open the link you were given.</p>")

    async def page(self, request: web.Request) -> web.StreamResponse:
        if await self._invite(request.match_info["token"]) is None:
            return _html(f"<p>{NOT_FOUND}</p>", status=404)
        return web.FileResponse(STATIC / "index.html", headers=HEADERS)

    async def join(self, request: web.Request) -> web.Response:
        """A Prolific link: an invite for the PROLIFIC_PID, then the page on its token."""
        ids = invites.prolific_ids(dict(request.query)) if self.options.prolific else None
        if ids is None:
            self.refused["bad_token"] += 1
            return _html(f"<p>{NOT_FOUND}</p>", status=404)
        loop = asyncio.get_running_loop()
        pairs = await loop.run_in_executor(
            None, lambda: invites.make_invites(self.engine, [ids["PROLIFIC_PID"]], prolific=ids)
        )
        raise web.HTTPSeeOther(f"/s/{pairs[0][1]}")

    # -------------------------------------------------------------- the participant

    async def participant_ws(self, request: web.Request) -> web.StreamResponse:
        invite = await self._invite(request.match_info["token"])
        if invite is None:
            return _html(f"<p>{NOT_FOUND}</p>", status=404)
        handle = self.sessions.get(invite.token_sha256)
        if handle is None or not handle.alive:
            running = sum(1 for h in self.sessions.values() if h.alive)
            if running >= self.options.max_sessions:
                self.refused["full"] += 1
                return _html("<p>The study is full just now. Please try again later.</p>", 503)
            handle = self._start(invite, handle)
        ws = web.WebSocketResponse(max_msg_size=MAX_WS_MESSAGE, heartbeat=10.0)
        await ws.prepare(request)
        await handle.attach(ws)
        pump = asyncio.create_task(handle.pump(ws))
        try:
            await handle.receive(ws)
        finally:
            handle.detach(ws)
            handle.wake.set()
            pump.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await pump
        return ws

    def _start(self, invite: invites.InviteInfo, old: SessionHandle | None) -> SessionHandle:
        o = self.options
        job = SessionJob(
            protocol=o.protocol, db=o.db, code=invite.code, token_sha256=invite.token_sha256,
            prolific=invite.prolific, recordings=o.recordings, site=o.site, camera=o.camera,
        )  # fmt: skip
        handle = SessionHandle(job)
        if old is not None:
            handle.drops, handle.takeovers = old.drops, old.takeovers
        handle.start(asyncio.get_running_loop())
        self.sessions[invite.token_sha256] = handle
        return handle

    # -------------------------------------------------------------- the experimenter

    def _experimenter_ok(self, request: web.Request) -> bool:
        given = request.query.get("token", "")
        return hmac.compare_digest(given.encode(), self.options.experimenter_token.encode())

    async def experimenter(self, request: web.Request) -> web.StreamResponse:
        if not self._experimenter_ok(request):
            self.refused["bad_token"] += 1
            return _html(f"<p>{NOT_FOUND}</p>", status=404)
        return web.FileResponse(STATIC / "experimenter.html", headers=HEADERS)

    def overview(self, trials: dict[str, dict[str, Any]]) -> dict[str, Any]:
        """Every session the server has run, for the experimenter's view, with its running
        trial (``trials``: code -> phase, ordinal, mode) where it has one."""
        return {
            "type": "sessions",
            "sessions": [
                {**h.summary(), "trial": trials.get(h.code)} for h in self.sessions.values()
            ],
            "refused": dict(self.refused),
            "at": time.time(),
        }

    def running_trials(self) -> dict[str, dict[str, Any]]:
        """Participant code -> its running trial's phase, ordinal, attempt and mode (the
        mode is the experimenter's to see, never the participant's)."""
        with Session(self.engine) as s:
            rows = s.execute(
                select(Participant.code, Trial.phase, Trial.ordinal, Trial.attempt, Trial.mode)
                .join(Participant, Participant.id == Trial.participant_id)
                .where(Trial.status == "running")
            ).all()
        return {r[0]: {"phase": r[1], "ordinal": r[2], "attempt": r[3], "mode": r[4]} for r in rows}

    async def experimenter_ws(self, request: web.Request) -> web.StreamResponse:
        if not self._experimenter_ok(request):
            self.refused["bad_token"] += 1
            return _html(f"<p>{NOT_FOUND}</p>", status=404)
        ws = web.WebSocketResponse(max_msg_size=4096, heartbeat=10.0)
        await ws.prepare(request)
        feed = asyncio.create_task(self._feed(ws))
        try:
            async for msg in ws:
                if msg.type == WSMsgType.TEXT:
                    self._experimenter_message(msg.data)
        finally:
            feed.cancel()
        return ws

    async def _feed(self, ws: web.WebSocketResponse) -> None:
        loop = asyncio.get_running_loop()
        maps: dict[str, bytes] = {}  # the maps this view has
        while not ws.closed:
            trials = await loop.run_in_executor(None, self.running_trials)
            with contextlib.suppress(ConnectionError, RuntimeError):
                for handle in self.sessions.values():
                    if handle.map is not None and maps.get(handle.code) is not handle.map:
                        maps[handle.code] = handle.map
                        await ws.send_str(json.dumps({"type": "map", "code": handle.code}))
                        await ws.send_bytes(handle.map)
                await ws.send_str(json.dumps(self.overview(trials)))
            await asyncio.sleep(STATUS_EVERY_S)

    def _experimenter_message(self, text: str) -> None:
        """``{"type": "abort", "code": ...}``: the experimenter aborts that session (the
        trial running is stored aborted with the reason, or the session on a page)."""
        with contextlib.suppress(ValueError, TypeError, AttributeError):
            msg = json.loads(text)
            if msg.get("type") == "abort":
                for handle in self.sessions.values():
                    if handle.code == msg.get("code") and handle.alive:
                        handle.stop("aborted by the experimenter")

    async def _shutdown(self, app: web.Application) -> None:
        for handle in self.sessions.values():
            if handle.alive:
                handle.stop("the study server stopped")
        loop = asyncio.get_running_loop()
        for handle in self.sessions.values():
            if handle.proc is not None:
                await loop.run_in_executor(None, handle.proc.join, 15)
                if handle.proc.is_alive():
                    handle.proc.terminate()
        self.engine.dispose()


def _html(body: str, status: int = 200) -> web.Response:
    page = (
        "<!doctype html><html lang='en'><head><meta charset='utf-8'><title>Robot study"
        f"</title></head><body>{body}</body></html>"
    )
    return web.Response(text=page, status=status, content_type="text/html", headers=HEADERS)


def serve(options: ServeOptions, *, host: str, port: int, ready: Any = None) -> None:
    """Run the server until interrupted (``ready(port)`` is called once it listens)."""
    server = StudyServer(options)

    async def main() -> None:
        runner = web.AppRunner(server.app(), handle_signals=False)
        await runner.setup()
        site = web.TCPSite(runner, host, port)
        await site.start()
        bound = site._server.sockets[0].getsockname()[1] if site._server else port  # type: ignore[union-attr]
        if ready is not None:
            ready(bound)
        try:
            await asyncio.Event().wait()
        finally:
            await runner.cleanup()

    with contextlib.suppress(KeyboardInterrupt):
        asyncio.run(main())
