"""Where a session runs in a multi-site study (issue 24): the site, one of the study's
``[study] sites``, and the machine, and the checks that keep a participant at one site.

A study without sites takes no site; a study with sites needs one for every session (the
site's counterbalancing ledger gives the participant's order, :mod:`study.data.ledger`).
The command line takes ``--site`` / ``--machine``, or the environment's ``ASA_SITE`` /
``ASA_MACHINE`` (set once on a lab machine); the machine defaults to the host name."""

from __future__ import annotations

import os
import socket
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

SITE_ENV = "ASA_SITE"
MACHINE_ENV = "ASA_MACHINE"


def _host() -> str:
    return socket.gethostname()[:128] or "unknown"


@dataclass(frozen=True, slots=True)
class Place:
    """Where a session runs: ``site`` (None in a study without sites) and ``machine`` (at
    most 128 characters: the host name unless given)."""

    site: str | None = None
    machine: str = field(default_factory=_host)

    @classmethod
    def given(cls, site: str | None, machine: str | None) -> Place:
        """The place from the command line's values, else the environment's, else no site
        and the host name."""
        site = site if site is not None else os.environ.get(SITE_ENV) or None
        machine = machine if machine is not None else os.environ.get(MACHINE_ENV) or None
        return cls(site, machine[:128]) if machine else cls(site)


def check_site(db: str | Path, place: Place, sites: Sequence[str], study: str) -> None:
    """Refuse (``ValueError``, one line naming the database and field) a session without a
    site in a study with sites, with a site the study does not have, or with a site in a
    study without sites."""
    if not sites:
        if place.site is not None:
            raise ValueError(
                f"{db}: field 'session.site': study '{study}' has no sites (the protocol's "
                f"[study] sites); run without --site (and unset {SITE_ENV})"
            )
        return
    names = ", ".join(sites)
    if place.site is None:
        raise ValueError(
            f"{db}: field 'session.site': study '{study}' runs at sites {names}; give the "
            f"session's site with --site (or {SITE_ENV})"
        )
    if place.site not in sites:
        raise ValueError(
            f"{db}: field 'session.site': {place.site!r} is not a site of study '{study}' "
            f"(its sites: {names})"
        )


def check_participant_site(db: str | Path, code: str, stored: str | None, place: Place) -> None:
    """Refuse a session of participant ``code`` at another site than the one it belongs to
    (codes are unique across sites: the same code at two sites is two people)."""
    if stored != place.site:
        raise ValueError(
            f"{db}: field 'participant.site': participant {code} belongs to site "
            f"{stored or '(none)'}, not {place.site or '(none)'}; participant codes are "
            "unique across sites, choose another code"
        )
