"""Study protocols shipped with the platform, as TOML files (data, not code)."""

from __future__ import annotations

from pathlib import Path

PROTOCOL_DIR = Path(__file__).resolve().parent


def available() -> list[str]:
    """Names of the shipped protocols (file stems), sorted."""
    return sorted(p.stem for p in PROTOCOL_DIR.glob("*.toml"))
