"""pybullet, imported without its build-time banner.

pybullet's C code prints "pybullet build time: ..." on stderr at import. Every
``asa`` command promises one line on stderr for bad input, so the banner is
swallowed here, once, by pointing file descriptor 2 at /dev/null during the
import. Everything else pybullet prints stays visible.
"""

from __future__ import annotations

import os
import sys
from types import ModuleType


def _import_quietly() -> ModuleType:
    try:
        fd = sys.stderr.fileno()
    except (AttributeError, OSError, ValueError):  # no real stderr (e.g. captured)
        import pybullet

        return pybullet
    sys.stderr.flush()
    saved = os.dup(fd)
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, fd)
        import pybullet
    finally:
        os.dup2(saved, fd)
        os.close(saved)
        os.close(devnull)
    return pybullet


pybullet = _import_quietly()
