"""Each participant's mode order under a protocol's counterbalancing scheme, and its
balance check (``asa plan``; thesis section 7.6.1.3); the order ledger of an existing
study (``asa plan --db``: every slot issued, its participant, order and status)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from sqlalchemy.orm import Session

from sim.limits import MAX_PARTICIPANTS, MAX_SEED
from study.data.ledger import RULE, entries
from study.data.storage import get_study, open_database
from study.engine.counterbalance import assign_indexed, balance
from study.engine.protocol import load_protocol, parse_protocol


def participant_code(i: int, n: int) -> str:
    """Pseudonymous code of participant ``i`` (from 0) of ``n``: ``P01``.. (at least 2 digits)."""
    return f"P{i + 1:0{max(2, len(str(n)))}d}"


def plan(
    protocol: str | Path, *, participants: int | None = None, seed: int | None = None
) -> dict[str, Any]:
    """The assignment of mode orders to participants and its balance check, JSON-ready.

    Parameters
    ----------
    protocol : str or Path
        A shipped protocol's name or a protocol file.
    participants : int, optional
        Number of participants; default the protocol's ``study.participants``.
    seed : int, optional
        Seed of the ``random`` scheme; default the protocol's ``study.seed``.

    Returns
    -------
    dict
        ``protocol`` (name), ``source``, ``sha256``, ``scheme``, ``seed``, ``participants``
        (list of ``{code, order_index, modes}``), ``balance`` (see
        :func:`study.engine.counterbalance.balance`), ``balanced`` and ``warnings``.
    """
    p = load_protocol(protocol)
    n = p.study.participants if participants is None else participants
    if isinstance(n, bool) or not isinstance(n, int) or not 1 <= n <= MAX_PARTICIPANTS:
        raise ValueError(f"participants: must be an integer in 1..{MAX_PARTICIPANTS}, got {n!r}")
    seed = p.study.seed if seed is None else seed
    if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed <= MAX_SEED:
        raise ValueError(f"seed: must be an integer in 0..{MAX_SEED}, got {seed!r}")
    rows = assign_indexed(p.modes, n, p.counterbalancing, rng=np.random.default_rng(seed))
    check = balance([modes for _, modes in rows], scheme=p.counterbalancing)
    return {
        "protocol": p.name,
        "source": p.source,
        "sha256": p.sha256,
        "scheme": p.counterbalancing,
        "seed": seed,
        "participants": [
            {"code": participant_code(i, n), "order_index": index, "modes": list(modes)}
            for i, (index, modes) in enumerate(rows)
        ],
        "balance": {k: v for k, v in check.items() if k not in ("balanced", "warnings")},
        "balanced": check["balanced"],
        "warnings": check["warnings"],
    }


def format_plan(result: dict[str, Any]) -> str:
    """The plan as text: one line per participant, then the balance tables and warnings."""
    b = result["balance"]
    modes, k = b["modes"], len(b["modes"])
    lines = [
        f"protocol {result['protocol']} ({result['source']}), sha256 {result['sha256'][:12]}",
        f"scheme {result['scheme']}, {b['n']} participants"
        + (f", cycle {b['cycle']}" if b["cycle"] else f", seed {result['seed']}"),
        "",
        "participant  row  order",
    ]
    for row in result["participants"]:
        lines.append(f"{row['code']:<11}  {row['order_index']:>3}  {' > '.join(row['modes'])}")
    width = max(len(m) for m in modes)
    lines += ["", "times in each position"]
    lines.append(f"  {'mode':<{width}}  " + "  ".join(f"{p + 1:>4}" for p in range(k)))
    for m in modes:
        counts = b["position_counts"][m]
        lines.append(f"  {m:<{width}}  " + "  ".join(f"{c:>4}" for c in counts))
    lines += ["", "times one mode directly follows another (row, then column)"]
    lines.append(f"  {'':<{width}}  " + "  ".join(f"{m:>{width}}" for m in modes))
    for a in modes:
        cells = ["-" if a == c else str(b["pair_counts"][f"{a}>{c}"]) for c in modes]
        lines.append(f"  {a:<{width}}  " + "  ".join(f"{c:>{width}}" for c in cells))
    lines += [
        "",
        f"position balanced: {'yes' if b['position_balanced'] else 'no'}; "
        f"carry-over balanced: {'yes' if b['carryover_balanced'] else 'no'}; "
        f"every order equally often: {'yes' if b['fully_counterbalanced'] else 'no'}",
        f"balanced for {result['scheme']}: {'yes' if result['balanced'] else 'NO'}",
    ]
    lines += [f"warning: {w}" for w in result["warnings"]]
    return "\n".join(lines)


def ledger(db: str | Path) -> dict[str, Any]:
    """The order ledger of the study in ``db``, JSON-ready: ``protocol`` (name), ``sha256``,
    ``scheme``, ``sites`` (the study's; [] without sites), ``rule`` (how slots are issued,
    :data:`study.data.ledger.RULE`), ``slots`` (list of ``{site, slot, code, order_index,
    modes, status, released}`` in site and slot order; ``status`` is the holder's last
    session's, ``excluded``, ``reserved`` or ``no session``; ``released`` the codes of
    excluded earlier holders), the ``balance`` of the orders of the slots' holders
    (:func:`balance`; pooled over the sites of a multi-site study: positions and
    carry-over, without the cycles, which are each site's), None without any, and
    ``balance_by_site`` (site -> balance, {} without sites).

    Raises
    ------
    ValueError
        Naming the database, when it is not a study database or holds no study.
    """
    engine = open_database(db, create=False)
    try:
        with Session(engine) as s:
            study = get_study(s)
            if study is None:
                raise ValueError(f"{db}: field 'study': no study in this database yet")
            rows = entries(s, study.id)
            name, sha, text = study.name, study.protocol_sha256, study.protocol_text
            sites = [str(x) for x in study.sites or []]
    finally:
        engine.dispose()
    try:
        scheme = parse_protocol(text, "<stored protocol>").counterbalancing
    except ValueError:
        scheme = None

    def balanced(site: str | None) -> dict[str, Any] | None:
        """The balance of a site's orders, or of every order (pooled over the sites: of
        positions and carry-over only, the cycles being each site's)."""
        orders = [r.mode_order for r in rows if r.mode_order and site in (None, r.site)]
        pooled = site is None and bool(sites)
        return balance(orders, scheme=None if pooled else scheme) if orders else None

    by_site = {site: balanced(site) for site in sites}
    return {
        "protocol": name,
        "sha256": sha,
        "scheme": scheme,
        "sites": sites,
        "rule": RULE,
        "slots": [
            {
                "site": r.site,
                "slot": r.slot,
                "code": r.code,
                "order_index": r.order_index,
                "modes": list(r.mode_order),
                "status": r.status,
                "released": list(r.released),
            }
            for r in rows
        ],  # fmt: skip
        "balance": balanced(None),
        "balance_by_site": {k: v for k, v in by_site.items() if v is not None},
    }


def _ledger_line(r: dict[str, Any]) -> str:
    row = "-" if r["order_index"] is None else str(r["order_index"])
    line = f"{r['slot']:>4}  {r['code']:<11}  {row:>3}  {r['status']:<10}  "
    line += " > ".join(r["modes"]) if r["modes"] else "-"
    if r["released"]:
        line += f"  (released by {', '.join(r['released'])})"
    return line


def _verdict(label: str, b: dict[str, Any] | None) -> list[str]:
    if b is None:
        return []
    return [f"{label}: {'yes' if b['balanced'] else 'no'}"] + [
        f"warning: {w}" for w in b["warnings"]
    ]


def format_ledger(result: dict[str, Any]) -> str:
    """The ledger as text: the rule, one line per slot (under a heading per site in a
    multi-site study), then the balance verdicts and warnings."""
    sites = result["sites"] or [""]
    lines = [
        f"study {result['protocol']}, sha256 {result['sha256'][:12]}, scheme {result['scheme']}",
        f"{len(result['slots'])} order slots issued"
        + (f" at {len(result['sites'])} sites" if result["sites"] else ""),
        f"rule: {result['rule']}",
    ]
    for site in sites + sorted({r["site"] for r in result["slots"]} - set(sites)):
        slots = [r for r in result["slots"] if r["site"] == site]
        if site and not slots:
            lines += ["", f"site {site}: no participant yet"]
            continue
        n = f"{len(slots)} slot" + ("" if len(slots) == 1 else "s")
        lines += ["", f"site {site}: {n}"] if site else [""]
        lines += ["slot  participant  row  status      order"]
        lines += [_ledger_line(r) for r in slots]
        if site:
            lines += _verdict(f"balanced for {result['scheme']} at {site}",
                              result["balance_by_site"].get(site))  # fmt: skip
    lines += [""] if result["balance"] is not None else []
    pooled = "pooled over the sites, positions and carry-over balanced"
    lines += _verdict(
        pooled if result["sites"] else f"balanced for {result['scheme']}", result["balance"]
    )
    return "\n".join(lines)
