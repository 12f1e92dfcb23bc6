"""Joining a browser session without a browser (issue 37): Prolific's links make an invite
of their own and continue on its token; the browser check refuses a slow connection or a
small window with the reasons, stores the result, and takes no order slot. A WebSocket
client stands in for the page (it answers the check and the pings as the page does)."""

from __future__ import annotations

import asyncio
import json

import aiohttp
from sqlalchemy import select
from sqlalchemy.orm import Session

from study.data.storage import Invite, Participant, open_database
from tests.web_helpers import served, short_protocol


async def _page(url: str, width: int) -> dict:
    """Answer the server as the page would; the message that ends it."""
    async with aiohttp.ClientSession() as http, http.ws_connect(url) as ws:
        async for msg in ws:
            if msg.type != aiohttp.WSMsgType.TEXT:
                continue
            m = json.loads(msg.data)
            if m["type"] == "check":
                check = {"width": width, "height": 800, "mobile": False, "gamepad": False}
                await ws.send_str(json.dumps({"type": "check", **check, "agent": "t"}))
            elif m["type"] == "ping":
                await asyncio.sleep(0.03)  # a slow connection: 30 ms more each way
                await ws.send_str(json.dumps({"type": "pong", "id": m["id"]}))
            elif m["type"] in ("refused", "screen", "aborted"):
                return m
    raise AssertionError("the server closed the page")


def test_a_slow_or_small_page_is_refused_with_the_reasons_and_no_slot(tmp_path, seed):
    protocol = short_protocol(tmp_path, seed % 1000)
    text = protocol.read_text().replace("latency_gate_ms = 500", "latency_gate_ms = 20")
    protocol.write_text(text)
    db = str(tmp_path / "web.db")
    with served(protocol, db) as server:
        ws_url = server.links["P01"].replace("http://", "ws://").replace("/s/", "/ws/")
        refused = asyncio.run(_page(ws_url, width=800))
    assert refused["type"] == "refused" and len(refused["reasons"]) == 2
    assert "800 x 800" in refused["reasons"][0] and "too slow" in refused["reasons"][1]
    engine = open_database(db, create=False)
    with Session(engine) as s:
        (invite,) = s.scalars(select(Invite)).all()
        assert invite.status == "refused" and not invite.checks[0]["passed"]
        assert invite.checks[0]["rtt_median_ms"] > 20
        assert s.scalars(select(Participant)).all() == []  # no order slot taken
    engine.dispose()


def test_a_prolific_link_makes_its_invite_and_continues_on_a_token(tmp_path, seed):
    protocol = short_protocol(tmp_path, seed % 1000)
    db = str(tmp_path / "web.db")
    ids = {"PROLIFIC_PID": "5f8a9b", "STUDY_ID": "s77", "SESSION_ID": "x1"}

    async def join(base: str) -> tuple[int, str, int]:
        async with aiohttp.ClientSession() as http:
            async with http.get(f"{base}/join", params=ids, allow_redirects=False) as r:
                status, where = r.status, r.headers.get("Location", "")
            async with http.get(f"{base}/join", params={**ids, "STUDY_ID": "a b"}) as r:
                bad = r.status
        return status, where, bad

    with served(protocol, db, "--prolific", codes=()) as server:
        status, where, bad = asyncio.run(join(server.base))
    assert status == 303 and where.startswith("/s/") and bad == 404
    engine = open_database(db, create=False)
    with Session(engine) as s:
        (invite,) = s.scalars(select(Invite)).all()
        assert invite.code == "5f8a9b" and invite.prolific == ids
    engine.dispose()
