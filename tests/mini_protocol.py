"""The small protocols the storage tests run (sessions of one or two short main trials),
written from one template instead of a TOML text per test file."""

from __future__ import annotations

import json
from collections.abc import Sequence


def mini_protocol(
    *,
    name: str = "mini",
    participants: int = 4,
    seed: int = 5,
    sites: Sequence[str] = (),
    modes: Sequence[str] = ("manual", "reactive_bn"),
    scheme: str = "full_permutation",
    camera_hz: float | None = None,
    experience: bool = False,
    baseline_questions: int = 0,
    timeout_s: float = 2.0,
    tlx: bool = False,
) -> str:
    """A protocol's TOML text: one main phase on practice_course (A -> B, no inspection,
    no secondary task, ``timeout_s`` a trial); optionally the study's ``sites``, a
    ``[recording] camera_hz``, the experience questionnaire, a baseline of
    ``baseline_questions`` and the raw NASA-TLX after each main trial."""
    lines = ["[study]", f'name = "{name}"', f"participants = {participants}", f"seed = {seed}"]
    lines += [f"sites = {json.dumps(list(sites))}"] if sites else []
    lines += ["", "[modes]", f"names = {json.dumps(list(modes))}"]
    lines += [f'counterbalancing = "{scheme}"']
    if camera_hz is not None:
        lines += ["", "[recording]", f"camera_hz = {camera_hz:g}"]
    if experience:
        lines += ["", "[[phases]]", 'kind = "experience"', 'instrument = "experience"']
    if baseline_questions:
        lines += ["", "[[phases]]", 'kind = "baseline"', f"questions = {baseline_questions}"]
    lines += ["", "[[phases]]", 'kind = "main"', 'scenario = "practice_course"']
    lines += ['route = ["A", "B"]', "inspection = false", "secondary = false"]
    lines += [f"timeout_s = {timeout_s:g}"]
    if tlx:
        lines += ["", "[phases.after_trial]", 'instrument = "nasa_tlx"', 'weights = "raw"']
    return "\n".join(lines) + "\n"
