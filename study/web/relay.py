"""The server's side of one session (docs/decisions.md, "Participants in a browser"): its
process and pipe, the page attached to it, and the messages between them. It knows
messages, not the trial loop: every message from the page is checked
(:mod:`study.web.messages`), stamped with the monotonic clock when it arrived and
forwarded; a bad one (oversized, malformed, out of order, beyond the flood limit) is
dropped and counted. What the session sends goes to the page in order, camera frames
latest-wins. One page at a time: a second one takes the session over and the first is
told and closed.
"""

from __future__ import annotations

import asyncio
import contextlib
import multiprocessing as mp
import time
from collections import Counter, deque
from typing import Any

from aiohttp import WSMsgType, web

from study.web import messages as wire
from study.web.session_proc import SessionJob, session_main

FLOOD_PER_S = 240  # messages a page may send a second (input at 60 fps and the rest)
OUTBOX = 400  # messages queued for a slow page before the oldest are dropped
DROPS_EVERY_S = 1.0  # [s] drop counts forwarded to the session at most this often


class SessionHandle:
    """One participant's session as the server sees it.

    Parameters
    ----------
    job : SessionJob
        What the session process runs.
    """

    def __init__(self, job: SessionJob) -> None:
        self.job = job
        self.code = job.code
        self.proc: Any = None
        self.conn: Any = None
        self.ws: web.WebSocketResponse | None = None
        self.status: dict[str, Any] = {}
        self.drops: Counter[str] = Counter()  # over the session's life, by reason
        self._unsent: Counter[str] = Counter()  # not yet told to the session
        self._drops_at = 0.0
        self.last_seq = -1
        self._window = (0.0, 0)  # flood window: start [s], messages in it
        self.outbox: deque[bytes | str] = deque(maxlen=OUTBOX)
        self.latest: dict[str, bytes | str] = {}
        self.wake = asyncio.Event()
        self.started = time.time()
        self.takeovers = 0
        self.map: bytes | None = None  # the scene's MAP message, for the experimenter's view

    # -------------------------------------------------------------- the process

    @property
    def alive(self) -> bool:
        return self.proc is not None and self.proc.is_alive()

    def start(self, loop: asyncio.AbstractEventLoop) -> None:
        """Start the session's process and listen to its pipe."""
        ctx = mp.get_context("spawn")
        self.conn, child = ctx.Pipe()
        self.proc = ctx.Process(
            target=session_main, args=(child, self.job), name=f"asa-session-{self.code}"
        )
        self.proc.start()
        child.close()
        self.status = {}
        self.last_seq = -1
        loop.add_reader(self.conn.fileno(), self._from_session, loop)

    def tell(self, *msg: Any) -> None:
        """A message to the session process (dropped when it is gone)."""
        if self.conn is None:
            return
        with contextlib.suppress(OSError, EOFError, ValueError):
            self.conn.send(msg)

    def _from_session(self, loop: asyncio.AbstractEventLoop) -> None:
        """Everything the session's pipe holds now (called by the loop when readable)."""
        try:
            while self.conn is not None and self.conn.poll():
                msg = self.conn.recv()
                if msg[0] == "ws":
                    self._queue(msg[1], msg[2])
                elif msg[0] == "status":
                    self.status = {**self.status, **msg[1], "at": time.time()}
        except (EOFError, OSError):
            loop.remove_reader(self.conn.fileno())
            self.conn.close()
            self.conn = None
            if self.proc is not None:
                self.proc.join(timeout=0.1)
            self.status = {**self.status, "ended": True}

    def _queue(self, payload: bytes | str, latest: str) -> None:
        if isinstance(payload, bytes) and payload[:1] == bytes([wire.MAP]):
            self.map = payload
        if latest:
            self.latest[latest] = payload
        else:
            self.outbox.append(payload)
        self.wake.set()

    def stop(self, reason: str) -> None:
        """Ask the session to stop (the experimenter's abort, the server stopping)."""
        self.tell("stop", reason)

    # -------------------------------------------------------------- the page

    async def attach(self, ws: web.WebSocketResponse) -> None:
        """A page for this session: the one before is told and closed (never two drive)."""
        old, self.ws = self.ws, ws
        self.outbox.clear()
        self.latest.clear()
        self.last_seq = -1
        if old is not None and not old.closed:
            self.takeovers += 1
            with contextlib.suppress(ConnectionError, RuntimeError):
                await old.send_str(wire.server_json("taken_over"))
                await old.close(code=4001, message=b"taken over by another page")
        self.tell("open")

    def detach(self, ws: web.WebSocketResponse) -> None:
        """``ws`` closed: the session is told the page is gone unless another took over."""
        if self.ws is ws:
            self.ws = None
            self.tell("gone")

    async def pump(self, ws: web.WebSocketResponse) -> None:
        """Send the session's messages to ``ws`` while it is this session's page."""
        while self.ws is ws and not ws.closed:
            await self.wake.wait()
            self.wake.clear()
            try:
                while self.outbox and self.ws is ws:
                    await _send(ws, self.outbox.popleft())
                for key in list(self.latest):
                    await _send(ws, self.latest.pop(key))
            except (ConnectionError, RuntimeError):
                return

    async def receive(self, ws: web.WebSocketResponse) -> None:
        """Check and forward every message of ``ws`` until it closes."""
        async for msg in ws:
            if self.ws is not ws:
                break
            if msg.type == WSMsgType.BINARY:
                self._binary(msg.data)
            elif msg.type == WSMsgType.TEXT:
                self._text(msg.data)
            elif msg.type == WSMsgType.ERROR:
                break
            self._tell_drops()

    def _flooding(self) -> bool:
        now = time.monotonic()
        start, n = self._window
        if now - start >= 1.0:
            self._window = (now, 1)
            return False
        self._window = (start, n + 1)
        return n + 1 > FLOOD_PER_S

    def _drop(self, reason: str) -> None:
        self.drops[reason] += 1
        self._unsent[reason] += 1

    def _binary(self, data: bytes) -> None:
        if self._flooding():
            return self._drop("flood")
        if len(data) > wire.MAX_BINARY:
            return self._drop("oversized")
        try:
            msg = wire.unpack_input(data)
        except ValueError:
            return self._drop("malformed")
        if msg.seq <= self.last_seq:
            return self._drop("out_of_order")
        self.last_seq = msg.seq
        self.tell("in", time.monotonic(), msg)

    def _text(self, data: str) -> None:
        if self._flooding():
            return self._drop("flood")
        if len(data) > wire.MAX_TEXT:
            return self._drop("oversized")
        try:
            msg = wire.client_json(data)
        except ValueError:
            return self._drop("malformed")
        self.tell("in", time.monotonic(), msg)

    def _tell_drops(self) -> None:
        now = time.monotonic()
        if self._unsent and now - self._drops_at >= DROPS_EVERY_S:
            self.tell("drops", dict(self._unsent))
            self._unsent.clear()
            self._drops_at = now

    def summary(self) -> dict[str, Any]:
        """The experimenter's line for this session."""
        return {
            "code": self.code,
            "connected": self.ws is not None,
            "running": self.alive,
            "elapsed_s": round(time.time() - self.started),
            "drops": dict(self.drops),
            "takeovers": self.takeovers,
            **{k: v for k, v in self.status.items() if k != "at"},
        }


async def _send(ws: web.WebSocketResponse, payload: bytes | str) -> None:
    if isinstance(payload, bytes):
        await ws.send_bytes(payload)
    else:
        await ws.send_str(payload)
