"""The browser check before a session's first screen (issue 37): a desktop page at least
``[web] min_window`` large, a gamepad button pressed when the protocol's ``[web] gamepad``
asks for one, and the median round trip of ``[web] pings`` pings within
``[web] latency_gate_ms``, measured by the server (the page only answers). The result is
stored with the invite; a participant who fails is told why and may try again from the
same link. Docs: docs/decisions.md, "Participants in a browser".
"""

from __future__ import annotations

import statistics
import time
from typing import Any

from study.web import messages as wire
from study.web.link import Link
from study.web.settings import WebSettings

PONG_TIMEOUT_S = 2.0  # [s] a ping unanswered this long counts as lost
PING_EVERY_S = 0.05  # [s] between pings


class CheckAbandoned(Exception):
    """The page went away during the check, or the server stopped."""


def _wait_for(link: Link, kind: str, timeout_s: float, **match: Any) -> dict[str, Any] | None:
    """The page's next JSON message of ``kind`` (with ``match``ing fields) within
    ``timeout_s``; None when none came. Other messages and presses are dropped."""
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        link.changed.wait(0.01)
        link.changed.clear()
        if link.stopped:
            raise CheckAbandoned(link.stopped)
        _, msgs = link.take()
        for m in msgs:
            if m["type"] == kind and all(m.get(k) == v for k, v in match.items()):
                return m
    return None


def ping(link: Link, count: int) -> list[float | None]:
    """Round trips [ms] of ``count`` pings (None: lost), on the server's monotonic clock."""
    rtts: list[float | None] = []
    for i in range(count):
        sent = time.monotonic()
        link.send(wire.server_json("ping", id=i))
        pong = _wait_for(link, "pong", PONG_TIMEOUT_S, id=i)
        rtts.append(None if pong is None else (pong["at"] - sent) * 1e3)
        time.sleep(PING_EVERY_S)
    return rtts


def browser_check(link: Link, web: WebSettings, timeout_s: float) -> dict[str, Any]:
    """Ask the page for its check, ping it; the result with ``passed`` and ``reasons``
    (what the participant is told)."""
    link.clear()
    link.send(wire.server_json("check", min_window=list(web.min_window), gamepad=web.gamepad))
    page = _wait_for(link, "check", timeout_s)
    if page is None:
        raise CheckAbandoned("the page sent no check")
    rtts = ping(link, web.pings)
    got = [r for r in rtts if r is not None]
    median = statistics.median(got) if got else None
    reasons = []
    if page["mobile"]:
        reasons.append("This study needs a desktop or laptop computer, not a phone or tablet.")
    w, h = web.min_window
    if page["width"] < w or page["height"] < h:
        reasons.append(
            f"Your browser window is {page['width']} x {page['height']} pixels; the study "
            f"needs at least {w} x {h}. Please make the window larger (or full screen)."
        )
    if web.gamepad and not page["gamepad"]:
        reasons.append("No gamepad button press was seen. Please connect a gamepad.")
    if median is None or median > web.latency_gate_ms:
        shown = "no answer" if median is None else f"{median:.0f} ms"
        reasons.append(
            f"The connection is too slow for the study: round trip {shown}, at most "
            f"{web.latency_gate_ms:g} ms. Please try from a faster connection."
        )
    return {
        "passed": not reasons, "reasons": reasons, "rtt_median_ms": median,
        "rtts_ms": [None if r is None else round(r, 2) for r in rtts],
        "lost": len(rtts) - len(got), "window": [page["width"], page["height"]],
        "mobile": page["mobile"], "gamepad": page["gamepad"], "agent": page["agent"],
        "at": time.time(),
    }  # fmt: skip
