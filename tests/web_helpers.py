"""The browser tests' helpers: :mod:`study.web.testing` (shared with ``asa bench --only
web``) and a TCP proxy whose connections a test cuts."""

from __future__ import annotations

import contextlib
from typing import Any

from study.web.testing import (  # noqa: F401
    DOWN,
    RIGHT,
    A,
    B,
    Person,
    browser,
    served,
    short_protocol,
)


class CuttableProxy:
    """A TCP proxy between the page and the server on 127.0.0.1 whose connections the test
    cuts (from the server's side as the page sees it) and whose port it can block."""

    def __init__(self, target_port: int) -> None:
        import socket
        import threading

        self.target = target_port
        self.blocked = False
        self.pairs: list[tuple[Any, Any]] = []
        self._lock = threading.Lock()
        self.listener = socket.create_server(("127.0.0.1", 0))
        self.port = self.listener.getsockname()[1]
        threading.Thread(target=self._accept, daemon=True).start()

    def _accept(self) -> None:
        import socket
        import threading

        while True:
            try:
                client, _ = self.listener.accept()
            except OSError:
                return
            if self.blocked:
                client.close()
                continue
            upstream = socket.create_connection(("127.0.0.1", self.target))
            with self._lock:
                self.pairs.append((client, upstream))
            for a, b in ((client, upstream), (upstream, client)):
                threading.Thread(target=self._pipe, args=(a, b), daemon=True).start()

    @staticmethod
    def _pipe(a: Any, b: Any) -> None:
        try:
            while data := a.recv(65536):
                b.sendall(data)
        except OSError:
            pass
        for s in (a, b):
            with contextlib.suppress(OSError):
                s.close()

    def cut(self) -> None:
        """Close every connection now."""
        import socket

        with self._lock:
            pairs, self.pairs = self.pairs, []
        for pair in pairs:
            for s in pair:
                with contextlib.suppress(OSError):
                    s.shutdown(socket.SHUT_RDWR)
                    s.close()

    def close(self) -> None:
        self.cut()
        self.listener.close()
