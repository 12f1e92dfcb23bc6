"""The report's Methods section: the platform, design, procedure, modes, measures and
analysis of one study, and every deviation from the thesis with its reason, as sentences a
researcher can paste into a paper (issue 18; thesis Sec. 7.5, 7.6).

Everything study-specific is read from the stored study (protocol text, platform version,
participants, the trials' stored mode settings); the deviations are :data:`DEVIATIONS`,
which docs/methods.md lists in full.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass
from pathlib import PurePath
from typing import Any

import pandas as pd

from analysis.data import Frames, StudyData


@dataclass(frozen=True, slots=True)
class Deviation:
    """One way the platform departs from the thesis, or fills a gap it leaves.

    Attributes
    ----------
    topic : short name ("Simulation", "Contextual mode: candidates", ...).
    modes : the modes it concerns (empty: every study).
    text : the sentence for a methods section, with the reason and the thesis section.
    protocols : the protocols (their ``[study] name``) it concerns (empty: any).
    """

    topic: str
    modes: tuple[str, ...]
    text: str
    protocols: tuple[str, ...] = ()


DEVIATIONS: tuple[Deviation, ...] = (
    Deviation(
        "Simulation",
        (),
        "The robot, its two laser scanners, IMU and camera and the scene are simulated in "
        "pybullet at a 20 Hz control tick instead of Gazebo and ROS (thesis Sec. 7.6.1: the "
        "study was run in simulation to remove hardware confounds); sensor noise is Gaussian "
        "as in Sec. 7.6.1.1.",
    ),
    Deviation(
        "Synthetic participants",
        (),
        "Synthetic participants, where present, are a behavioural model (route planning on "
        "the map, stick delay, tremor and overshoot, distraction by the questions, a "
        "NASA-TLX response model), not people; their results show what the protocol and "
        "analysis do, not how people behave.",
    ),
    Deviation(
        "Training and practice limits",
        (),
        "The training time per mode, the practice course's time limit and its number of "
        "attempts are the protocol's choices (the thesis gives \u201ca specific time "
        "limit\u201d and no duration or number of attempts, Sec. 7.6.1.3); the Procedure "
        "paragraph gives the values used.",
    ),
    Deviation(
        "Secondary task timeout",
        (),
        "A question not answered within the protocol's question timeout counts as an error "
        "(the thesis gives no timeout, Sec. 7.6.1.2).",
    ),
    Deviation(
        "Timed-out trials",
        (),
        "A main trial ends as timed out at the protocol's time limit (the thesis gives none); "
        "its completion time and score are not measured times and are treated as the "
        "protocol's [analysis] timeouts says (missing, or censored at the limit).",
    ),
    Deviation(
        "Reactive mode: arbitration",
        ("reactive_bn",),
        "The reactive mode executes the most probable situation's action exclusively (free "
        "travel: the user's command; object approach: stop at the safety distance; general "
        "obstacle avoidance: the dynamic window's command, or stop when none is admissible), "
        "as Sec. 3.2.1.1 describes; the blend of Eq. 3.2 with beta = the maximum posterior "
        '(Eq. 3.11), which the thesis also states, is the setting arbitration = "blend".',
    ),
    Deviation(
        "Reactive mode: turning and the dynamic window",
        ("reactive_bn",),
        "With exclusive arbitration, object approach attenuates the translation only "
        "(Eq. 3.6 and 3.7) and keeps the rotation, slowed only where the robot's corners "
        "would sweep into the protective field, so that an operator near a wall can turn "
        "away; the dynamic window's clearance term is weighted by each motion's progress "
        "along the user's command, so that stopping never scores better than an admissible "
        "motion the user asks for (not in the thesis; without it the robot stayed at rest "
        "in front of narrow doorways).",
    ),
    Deviation(
        "Sec. 7.5 robot and scene",
        (),
        "The thesis's Sec. 7.5 study flew a simulated quadrotor of radius 0.39 m through an "
        "office; here the platform's holonomic ground robot (0.6 m x 0.5 m) drives the study "
        "scene's path through narrow doorways, gaps and a corridor. The screen is the "
        "thesis's Fig. 7.42: the robot-centred laser scan with the stick arrow, the front "
        "and the tail camera, no map.",
        ("reactive-7-5",),
    ),
    Deviation(
        "Sec. 7.5 clearance and crashes",
        (),
        "Clearance is the minimum distance from the robot's centre to the laser hits of both "
        "scanners, as a 360-degree scanner at the centre would read it (Table 7.10 reports "
        "\u201cdistances ... recorded by the LRF\u201d); a collision ends the trial as a crash, "
        "whose clearance Table 7.10 gives as zero and whose samples Fig. 7.44(b) leaves out.",
        ("reactive-7-5",),
    ),
    Deviation(
        "Contextual mode: candidates",
        ("contextual_task",),
        "The contextual mode considers the 10 semantic components nearest the robot as "
        "candidates each tick (the thesis does not bound the candidate set, Sec. 6.2.2), to "
        "keep the tick within its time budget.",
    ),
    Deviation(
        "Contextual mode: no assistance without input",
        ("contextual_task",),
        "Below 5 % of full translational stick deflection the contextual mode does not "
        "assist (no user intention to recognise); the command then passes the safety layer "
        "only.",
    ),
    Deviation(
        "Contextual mode: yielding",
        ("contextual_task",),
        "Whenever the safety layer must slow the blended command and the user's own "
        "command, checked alike, gets further along the user's input, the contextual mode "
        "yields for that tick (beta = 0, the user's safe command), so that the assistance "
        "never holds the robot back where the user's command would pass. Where the safety "
        "layer would slow the user's command too, the command yielded to is the reactive "
        "mode's dynamic-window twist nearest it (Eq. 3.8) when that gets further, so a "
        "robot a wrong recognition has pushed off a doorway's axis slides back instead of "
        "standing with the stick held (not in the thesis; the safety layer itself is "
        "Sec. 7.6.1.2, footnote 31).",
    ),
    Deviation(
        "Contextual mode: tracking",
        ("contextual_task",),
        "The predicted trajectory is tracked by a holonomic pure-pursuit controller instead "
        "of the ROS navigation stack used in the thesis (Sec. 6.2.3).",
    ),
    Deviation(
        "Contextual mode: recogniser",
        ("contextual_task",),
        "The shipped recogniser is trained on scripted demonstrations of the four "
        "demonstrated task types (Sec. 7.4.1) with two other nearby components' features per "
        "way point as negatives in every one-vs-all GP; its SOGPs keep 250 basis vectors "
        "(the thesis: 500) to keep the model file small; the DP-GMM is truncated at 20 "
        "components and clusters under 4 % of the points are merged into their nearest.",
    ),
    Deviation(
        "Contextual mode: the component's kind and time",
        ("contextual_task",),
        'By default (recogniser = "kind_time") the contextual mode recognises the driver\'s '
        "task from the semantic component's kind and over time, not per tick from the task "
        "feature alone (Ch. 6): each candidate's SOGP scores (Eq. 5.6) are combined with the "
        "share of each motion primitive's demonstrations performed on that kind of component, "
        "the distances at which the primitive was executed rather than approached, and the "
        "target's rank among the nearest components, all learnt from the unlabelled "
        "demonstrations (the target component, and so its kind, is known without a task "
        "label, Sec. 6.2.1; gaps and docks reach the primitives as doorway-like point "
        "targets, Sec. 4.2.4), plus the progress along a passage's axis; the belief is "
        "filtered with the Ch. 4 recogniser's sticky transition and Bayes update (Eq. 4.4, "
        "4.14) with a no-task hypothesis, and the blend weight is the winner's posterior only "
        "when it is decisive (else 0), withdrawn when the driver pushes against the "
        "assistance. The thesis's recogniser (Eq. 5.8 per tick, beta of Eq. 5.10) is the "
        'setting recogniser = "thesis"; the Methods name the one a study ran.',
    ),
    Deviation(
        "Contextual mode: task labels",
        ("contextual_task",),
        "A recognised primitive is reported as the contextual task it performs on the "
        "recognised component: the component's kind names the task (doorway, gap, dock, "
        "wall) and, for objects, the primitive's dominant demonstrated motion decides "
        "between inspection and bypass (Sec. 4.2.4, 7.4.2).",
    ),
)


def _protocol(data: StudyData) -> dict[str, Any]:
    try:
        return tomllib.loads(str(data.study.get("protocol_text") or ""))
    except tomllib.TOMLDecodeError:
        return {}


def _people(frames: Frames) -> str:
    kinds = frames.participants["kind"].value_counts().to_dict()
    parts = [f"{n} {kind}" for kind, n in sorted(kinds.items())]
    return f"{int(sum(kinds.values()))} participants ({', '.join(parts)})"


def _platform(data: StudyData, protocol: dict[str, Any]) -> str:
    s = data.study
    name = (protocol.get("study") or {}).get("name") or s.get("name", "")
    sha = str(s.get("protocol_sha256") or "")[:12]
    return (
        f"The study was run with asa-study {s.get('platform_version', '?')} (protocol "
        f"\u201c{name}\u201d, SHA-256 {sha}\u2026, study seed {s.get('seed', '?')}); the "
        "protocol text and every control tick are stored with the data."
    )


def _design(frames: Frames, protocol: dict[str, Any]) -> str:
    modes = protocol.get("modes") or {}
    scheme = str(modes.get("counterbalancing") or "the protocol's scheme").replace("_", " ")
    hidden = " The participant was not told which mode was active." if modes.get("hidden") else ""
    return (
        f"{_people(frames)} drove in a within-subjects design with the control mode as the "
        f"only factor ({', '.join(frames.modes)}); the order of the modes was balanced by "
        f"{scheme} counterbalancing.{hidden}"
    )


_INSTRUMENTS = {"nasa_tlx": "the NASA-TLX"}
_WEIGHTS = {
    "per_trial": "ratings and the 15 pairwise comparisons after every trial",
    "once": "ratings after every trial, the pairwise comparisons once",
    "raw": "ratings only",
}
_GATES = {
    "auto": "the corrected p when Mauchly's test rejects sphericity",
    "uncorrected": "the uncorrected p",
    "greenhouse_geisser": "always the corrected p",
}


def _phase(p: dict[str, Any]) -> str:
    kind = p.get("kind", "")
    if kind == "training":
        questions = ", with questions" if p.get("secondary") else ""
        if p.get("secondary") and p.get("rehearsal_questions"):
            questions += (
                f", the first {int(p['rehearsal_questions'])} at the start of each run "
                "wherever the robot was"
            )
        return (
            f"training in {p.get('scenario')} ({p.get('duration_s', 0):.0f} s per mode{questions})"
        )
    if kind == "practice":
        fail = "excluded" if p.get("on_fail") == "exclude" else "kept"
        hits = int(p.get("max_collisions", 0))
        clean = "without a collision" if hits == 0 else f"with at most {hits} collisions"
        return (
            f"a practice course ({p.get('scenario')}) once per mode, to be finished within "
            f"{p.get('time_limit_s', 0):.0f} s {clean} in at most {p.get('max_attempts', 1)} "
            f"attempts (a participant who fails them all is {fail})"
        )
    if kind == "baseline":
        return f"{p.get('questions', 0)} arithmetic questions without driving (the baseline)"
    if kind == "main":
        route = " \u2192 ".join(p.get("route") or [])
        parts = [f"one main trial per mode in {p.get('scenario')} along {route}"]
        if p.get("inspection"):
            parts.append("inspecting the object on the way")
        if p.get("secondary"):
            parts.append(f"questions in blocks of {p.get('block_size', '?')} in the marked region")
        parts.append(f"a time limit of {p.get('timeout_s', 0):.0f} s")
        if p.get("end_on_collision"):
            parts.append("a collision ending the trial as a crash")
        after = p.get("after_trial") or {}
        if after:
            parts.append(
                f"followed by {_INSTRUMENTS.get(after.get('instrument'), 'a questionnaire')}"
                f" ({_WEIGHTS.get(after.get('weights'), after.get('weights'))})"
            )
        return ", ".join(parts)
    return {"briefing": "a briefing", "experience": "an experience questionnaire"}.get(kind, "")


def _procedure(protocol: dict[str, Any]) -> str:
    steps = [s for s in (_phase(p) for p in protocol.get("phases") or []) if s]
    if not steps:
        return "The protocol's phases are not stored with this study."
    timeout = (protocol.get("secondary") or {}).get("timeout_s")
    tail = f" A question unanswered after {timeout:g} s counted as an error." if timeout else ""
    return f"Each session consisted of {'; '.join(steps)}.{tail}"


def _stored_outcome(data: StudyData, mode: str) -> dict[str, Any] | None:
    """The outcome of the first trial of ``mode`` that stored its mode settings."""
    trials = data.tables.get("trial", pd.DataFrame())
    if trials.empty or "outcome" not in trials:
        return None
    for mode_, outcome in zip(trials["mode"], trials["outcome"], strict=True):
        if mode_ == mode and isinstance(outcome, dict) and "mode_settings" in outcome:
            return outcome
    return None


THESIS_RECOGNISER = "thesis (Ch. 6)"  # what a study stored before the setting existed ran


def _model_text(settings: dict[str, Any], outcome: dict[str, Any] | None) -> str:
    """The model a mode read, by file name and SHA-256 (issue 40), and the recogniser the
    mode ran; "" for a mode without a model. The absolute path is the machine's, not the
    study's, and is never printed."""
    path = settings.get("model_path")
    if not isinstance(path, str):
        return ""
    if not path:
        return "no model (manual behaviour)"
    stored = (outcome or {}).get("model")
    if isinstance(stored, dict) and stored.get("sha256"):
        name = f"model {stored.get('file', '?')} (SHA-256 {stored['sha256']})"
    else:
        name = f"model {PurePath(path).name} (SHA-256 not stored with this study's trials)"
    recogniser = settings.get("recogniser")
    which = THESIS_RECOGNISER if recogniser is None else str(recogniser)
    return f"{name}, recogniser {which}"


def _mode_text(mode: str, data: StudyData, protocol: dict[str, Any]) -> str:
    outcome = _stored_outcome(data, mode)
    stored = dict(outcome["mode_settings"]) if outcome is not None else None
    given = ((protocol.get("modes") or {}).get("settings") or {}).get(mode) or {}
    settings = stored if stored is not None else given
    model = _model_text(settings, outcome)
    shown = {
        k: v
        for k, v in sorted(settings.items())
        if not isinstance(v, dict | list) and k not in ("model_path", "recogniser")
    }
    if not shown and not model:
        where = "the platform's defaults (not stored with trials of this version)"
        return f"{mode}: {where}" if stored is None else f"{mode}: no settings"
    source = "as stored with its trials" if stored is not None else "as the protocol sets them"
    values = ", ".join([model] * bool(model) + [f"{k} = {v}" for k, v in shown.items()])
    return f"{mode} ({source}): {values}"


def _modes(frames: Frames, data: StudyData, protocol: dict[str, Any]) -> str:
    return "; ".join(_mode_text(m, data, protocol) for m in frames.modes) + "."


_POSTHOC_WORDS = {  # the protocol's posthoc (issue 21) as the Methods text names it
    "lsd_paired": "Fisher's LSD (lsd paired)",
    "lsd_pooled": "Fisher's LSD (lsd pooled)",
    "holm": "paired t-tests with Holm's correction",
    "bonferroni": "paired t-tests with Bonferroni's correction",
}


def posthoc_gate_words(posthoc: str, posthoc_gate: str) -> str:
    """When the planned post-hoc family ran, in the Methods text's words (see
    :func:`analysis.stats.posthoc_gated`)."""
    if posthoc_gate == "omnibus" or (posthoc_gate == "auto" and posthoc.startswith("lsd")):
        return "where the omnibus test rejected"
    if posthoc.startswith("lsd"):
        return "whatever the omnibus test gave (unprotected: no family-wise error control)"
    return "whatever the omnibus test gave (the correction controls the family-wise error)"


_TEST_WORDS = {  # the protocol's [analysis] test (issue 21) as the Methods text names it
    "friedman": "Friedman's test (with Kendall's W), followed by Wilcoxon signed-rank pairs "
    "with Holm's correction where it rejected",
    "auto": "the test planned per kind of metric: Friedman's test (Kendall's W; Wilcoxon "
    "pairs with Holm's correction) for counts with many ties and single rating items, "
    "else the repeated-measures ANOVA as above",
}


def _analysis(data: StudyData) -> str:
    c = data.config
    timeouts = (
        "left out as missing (the participant dropped listwise from that test)"
        if c.timeouts == "exclude"
        else "kept at the time limit as right-censored values"
    )
    gate = _GATES.get(c.gate, c.gate)
    anova = (
        f"a one-way repeated-measures ANOVA over the modes at \u03b1 = {c.alpha:g}, with "
        f"Mauchly's test and the Greenhouse\u2013Geisser correction ({gate}), followed by "
        f"{_POSTHOC_WORDS.get(c.posthoc, c.posthoc)} "
        f"{posthoc_gate_words(c.posthoc, c.posthoc_gate)}"
    )
    planned = [f"{m}: {_TEST_WORDS[t].split(' (')[0]}" for m, t in c.tests.items()]
    words = _TEST_WORDS.get(c.test, "")
    if c.posthoc_gate != "omnibus":  # Wilcoxon-Holm pairs are gated only then
        words = words.replace(" where it rejected", " whatever it gave")
    lead = anova if c.test == "rm_anova" else f"{words} (the ANOVA: {anova})"
    return (
        f"Each metric ({', '.join(c.metrics) or 'the report defaults'}) was analysed by "
        f"{lead}"
        + (f"; planned per metric: {'; '.join(planned)}" if planned else "")
        + "; effect sizes are partial eta squared with its 90 % interval (noncentral F) and "
        "generalised eta squared, and per pair the mean difference and Cohen's d_z with "
        "their intervals (noncentral t); the normality of the paired differences "
        "(Shapiro\u2013Wilk) and outliers (studentised residuals beyond 3) were checked; a "
        "linear mixed model (mode fixed, position in the order a covariate, a random "
        "intercept per participant; likelihood-ratio test of mode, ML fits) kept "
        "participants who missed a mode, and tested order effects (position, mode \u00d7 "
        f"position); the score is the completion time plus {c.collision_penalty_s:g} s per "
        f"collision; the completion time and score of timed-out trials were {timeouts} "
        "(thesis Sec. 7.6.2)."
    )


def methods(data: StudyData, frames: Frames) -> dict[str, Any]:
    """The Methods section of one study's report.

    Returns
    -------
    dict
        ``paragraphs``: list of {"title", "text"} (platform, design, procedure, modes,
        analysis); ``deviations``: list of {"topic", "text"}, those of :data:`DEVIATIONS`
        that concern one of the study's modes (or every mode) and its protocol (or any).
    """
    protocol = _protocol(data)
    paragraphs = [
        ("Platform", _platform(data, protocol)),
        ("Participants and design", _design(frames, protocol)),
        ("Procedure", _procedure(protocol)),
        ("Assistance modes", _modes(frames, data, protocol)),
        ("Analysis", _analysis(data)),
    ]
    modes = set(frames.modes)
    name = (protocol.get("study") or {}).get("name", "")
    deviations = [
        d
        for d in DEVIATIONS
        if (not d.modes or modes & set(d.modes)) and (not d.protocols or name in d.protocols)
    ]
    return {
        "paragraphs": [{"title": t, "text": x} for t, x in paragraphs],
        "deviations": [{"topic": d.topic, "text": d.text} for d in deviations],
    }


def methods_markdown(section: dict[str, Any]) -> str:
    """The Methods section of :func:`methods` as Markdown (``methods.md`` of a report)."""
    lines = ["# Methods", ""]
    for p in section["paragraphs"]:
        lines += [f"**{p['title']}.** {p['text']}", ""]
    lines += ["## Deviations from the thesis", ""]
    lines += [f"- *{d['topic']}.* {d['text']}" for d in section["deviations"]]
    return "\n".join(lines) + "\n"


__all__ = ["DEVIATIONS", "Deviation", "methods", "methods_markdown"]
