"""The study: protocols, counterbalancing, sessions, participants, storage,
recording and the ``asa`` command line."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("asa-study")
except PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0.0.0+unknown"
