"""pylsl and pyxdf, imported only when used: a missing extra or a missing liblsl is one
line saying how to get it (``ValueError``, which the CLI prints and exits 2 on)."""

from __future__ import annotations

import os
from pathlib import Path
from types import ModuleType

NO_PYLSL = (
    "LSL: pylsl is not installed; install the extra: pip install -e '.[lsl]' (its Linux "
    "x86_64 wheel ships liblsl; elsewhere also conda install -c conda-forge liblsl, or set "
    "PYLSL_LIB to the library file)"
)
NO_LIBLSL = (
    "LSL: pylsl cannot load liblsl ({reason}); pylsl's Linux x86_64 wheel ships it "
    "(glibc >= 2.35), otherwise install liblsl (conda install -c conda-forge liblsl) or "
    "set PYLSL_LIB to the library file"
)
# liblsl's own configuration files, in the order it reads them (after $LSLAPICFG)
CONFIG_FILES = ("lsl_api.cfg", "~/lsl_api/lsl_api.cfg", "/etc/lsl_api/lsl_api.cfg")
# without a configuration of the lab's: this machine only (streams are found and offered
# on this host, nothing multicast beyond it), liblsl's log off the experimenter's terminal
DEFAULT_CONFIG = "[multicast]\nResolveScope = machine\n[log]\nlevel = -3\n"
_configured = False

NO_PYXDF = "XDF: pyxdf is not installed; install the extra: pip install -e '.[lsl]'"


def pylsl() -> ModuleType:
    """The pylsl module with a working liblsl, or ``ValueError`` saying how to get one."""
    try:
        import pylsl as module
    except ImportError as error:
        if getattr(error, "name", "") == "pylsl":
            raise ValueError(NO_PYLSL) from None
        raise ValueError(NO_LIBLSL.format(reason=_one_line(error))) from None
    except RuntimeError as error:  # pylsl: "LSL binary library file was not found"
        raise ValueError(NO_LIBLSL.format(reason=_one_line(error))) from None
    _configure(module)
    return module


def _configure(module: ModuleType) -> None:
    """Once per process, before liblsl reads its configuration: a lab's configuration
    (``$LSLAPICFG`` or liblsl's files) is used as it is; without one,
    :data:`DEFAULT_CONFIG`: liblsl's defaults with the resolve scope this machine and the
    log level at fatal errors only."""
    global _configured
    if _configured:
        return
    _configured = True
    if os.environ.get("LSLAPICFG") or any(Path(f).expanduser().is_file() for f in CONFIG_FILES):
        return
    try:
        module.set_config_content(DEFAULT_CONFIG)
    except (AttributeError, RuntimeError):  # a liblsl older than 1.16: its defaults
        pass


def pyxdf() -> ModuleType:
    """The pyxdf module, or ``ValueError`` saying how to get it."""
    try:
        import pyxdf as module
    except ImportError:
        raise ValueError(NO_PYXDF) from None
    return module


def local_clock() -> float:
    """[s] LSL's clock on this machine (``pylsl.local_clock()``)."""
    return float(pylsl().local_clock())


def _one_line(error: BaseException) -> str:
    return " ".join(str(error).split())[:200] or type(error).__name__
