"""NASA Task Load Index: the six rating scales, the 15 pairwise comparisons, scoring.

Thesis Sec. 7.6.1.2 administers the NASA-TLX (Hart & Staveland 1988, the thesis's
reference [81]) after every trial; spec section 7. The wording of the six scales follows the
NASA-TLX paper-and-pencil manual (NASA Ames Research Center, 1986): titles, the "Rating
Scale Definitions" as each item's ``description``, the rating-sheet questions as its
``text`` and the endpoints "Very Low"/"Very High" ("Perfect"/"Failure" for Performance).
Each scale is marked at one of 21 ticks, recorded 0..100 in steps of 5, and oriented so that
higher means more workload (no scale is reversed). In the 15 pairwise comparisons the
participant picks the scale that contributed more to the workload; a scale's weight is how
often it was picked (0..5, summing to 15). Scoring: :func:`score`.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from questionnaires.base import Instrument, Item

INSTRUMENT_ID = "nasa_tlx"
PAIRS_INSTRUMENT_ID = "nasa_tlx_pairs"
RATING_VALUES: tuple[int, ...] = tuple(range(0, 101, 5))  # 21 marks
N_PAIRS = 15


@dataclass(frozen=True, slots=True)
class Subscale:
    """One NASA-TLX rating scale.

    Attributes
    ----------
    id : str
        ``"mental"``, ``"physical"``, ``"temporal"``, ``"performance"``,
        ``"effort"`` or ``"frustration"``.
    title : str
        As printed on the rating sheet.
    question : str
        The rating-sheet question.
    description : str
        The manual's rating scale definition.
    low, high : str
        Endpoint labels at rating 0 and 100.
    """

    id: str
    title: str
    question: str
    description: str
    low: str = "Very Low"
    high: str = "Very High"


SUBSCALES: tuple[Subscale, ...] = (
    Subscale(
        "mental",
        "Mental Demand",
        "How mentally demanding was the task?",
        "How much mental and perceptual activity was required (e.g., thinking, deciding, "
        "calculating, remembering, looking, searching, etc.)? Was the task easy or "
        "demanding, simple or complex, exacting or forgiving?",
    ),
    Subscale(
        "physical",
        "Physical Demand",
        "How physically demanding was the task?",
        "How much physical activity was required (e.g., pushing, pulling, turning, "
        "controlling, activating, etc.)? Was the task easy or demanding, slow or brisk, "
        "slack or strenuous, restful or laborious?",
    ),
    Subscale(
        "temporal",
        "Temporal Demand",
        "How hurried or rushed was the pace of the task?",
        "How much time pressure did you feel due to the rate or pace at which the tasks "
        "or task elements occurred? Was the pace slow and leisurely or rapid and frantic?",
    ),
    Subscale(
        "performance",
        "Performance",
        "How successful were you in accomplishing what you were asked to do?",
        "How successful do you think you were in accomplishing the goals of the task set "
        "by the experimenter (or yourself)? How satisfied were you with your performance "
        "in accomplishing these goals?",
        low="Perfect",
        high="Failure",
    ),
    Subscale(
        "effort",
        "Effort",
        "How hard did you have to work to accomplish your level of performance?",
        "How hard did you have to work (mentally and physically) to accomplish your level "
        "of performance?",
    ),
    Subscale(
        "frustration",
        "Frustration",
        "How insecure, discouraged, irritated, stressed, and annoyed were you?",
        "How insecure, discouraged, irritated, stressed and annoyed versus secure, "
        "gratified, content, relaxed and complacent did you feel during the task?",
    ),
)
SUBSCALE_IDS: tuple[str, ...] = tuple(s.id for s in SUBSCALES)
_TITLES = {s.id: s.title for s in SUBSCALES}

PAIRS: tuple[tuple[str, str], ...] = tuple(itertools.combinations(SUBSCALE_IDS, 2))
"""The 15 pairwise comparisons in canonical order (scale order, lexicographic)."""

RATING_INSTRUCTIONS = (
    "Please rate the task you have just completed on each of the six scales below by "
    "marking the point that best matches your experience. Each scale has 21 marks "
    "between the two labels at its ends."
)  # no numbers on screen (they could anchor the ratings); recorded 0..100 all the same
PAIRS_INSTRUCTIONS = (
    "For each of the following pairs, select the one that was the more important "
    "contributor to the workload of the task you have just completed."
)
PAIR_QUESTION = "Which contributed more to the workload of the task?"

INSTRUMENT = Instrument(
    id=INSTRUMENT_ID,
    title="NASA Task Load Index",
    instructions=RATING_INSTRUCTIONS,
    items=tuple(
        Item(
            id=s.id,
            text=s.question,
            kind="slider",
            values=RATING_VALUES,
            anchors=(s.low, s.high),
            title=s.title,
            description=s.description,
        )
        for s in SUBSCALES
    ),
)
"""The six rating scales as a generic instrument, in the manual's order."""


@dataclass(frozen=True, slots=True)
class TlxScore:
    """The NASA-TLX result of one questionnaire.

    Attributes
    ----------
    raw : float
        Unweighted mean of the six ratings, 0..100 (RTLX).
    weighted : float or None
        ``sum(rating * weight) / 15``, 0..100; ``None`` without weights.
    ratings : dict[str, int]
        Subscale id -> rating 0..100, in scale order.
    weights : dict[str, int] or None
        Subscale id -> times chosen in the pairwise comparisons, 0..5, sum 15.
    adjusted : dict[str, int] or None
        Subscale id -> rating * weight (the manual's "adjusted rating").
    """

    raw: float
    weighted: float | None
    ratings: dict[str, int]
    weights: dict[str, int] | None
    adjusted: dict[str, int] | None


def pair_id(a: str, b: str) -> str:
    """Stable id of the comparison of ``a`` and ``b``, canonical orientation.

    ``pair_id("effort", "mental") == pair_id("mental", "effort") == "mental_vs_effort"``.
    """
    pair = _canonical_pair((a, b), source="pair_id")
    return f"{pair[0]}_vs_{pair[1]}"


def presentation_order(rng: np.random.Generator) -> tuple[tuple[str, str], ...]:
    """The 15 comparisons in a random order, each with a random left/right placement.

    Parameters
    ----------
    rng : numpy.random.Generator
        The only source of randomness; the same generator state gives the same order.

    Returns
    -------
    tuple of (str, str)
        15 ``(left, right)`` pairs of subscale ids; every unordered pair exactly once.
    """
    order = rng.permutation(len(PAIRS))
    swap = rng.random(len(PAIRS)) < 0.5
    return tuple(
        (PAIRS[i][1], PAIRS[i][0]) if flip else PAIRS[i]
        for i, flip in zip(order, swap, strict=True)
    )


def comparison_instrument(rng: np.random.Generator) -> Instrument:
    """The pairwise comparisons as a generic instrument, in a seeded presentation order.

    Each item is a two-way choice with id :func:`pair_id`, values ``(left, right)``
    subscale ids and the scale titles as labels. The answers, item id -> chosen
    subscale id, go straight into :func:`weights_from_choices`.
    """
    items = tuple(
        Item(
            id=pair_id(left, right),
            text=PAIR_QUESTION,
            kind="choice",
            values=(left, right),
            labels=(_TITLES[left], _TITLES[right]),
            title=f"{_TITLES[left]} or {_TITLES[right]}",
        )
        for left, right in presentation_order(rng)
    )
    return Instrument(
        id=PAIRS_INSTRUMENT_ID,
        title="NASA-TLX: sources of workload",
        instructions=PAIRS_INSTRUCTIONS,
        items=items,
    )


def validate_ratings(ratings: Mapping[str, object], *, source: str = "NASA-TLX ratings") -> dict:
    """Check the six ratings; return them as ints in scale order.

    Raises
    ------
    ValueError
        On a missing or unknown subscale, or a rating that is not a multiple of 5
        from 0 to 100; the message names the subscale.
    """
    if not isinstance(ratings, Mapping):
        raise ValueError(f"{source}: must be a mapping of subscale id to rating")
    _check_keys(ratings, source)
    return INSTRUMENT.validate(ratings, source=source, noun="subscale")


def validate_weights(weights: Mapping[str, object], *, source: str = "NASA-TLX weights") -> dict:
    """Check the six weights; return them as ints in scale order.

    Raises
    ------
    ValueError
        On a missing or unknown subscale, a weight that is not a whole number
        0..5, weights not summing to 15, or weights no set of 15 choices can give.
    """
    if not isinstance(weights, Mapping):
        raise ValueError(f"{source}: must be a mapping of subscale id to weight")
    _check_keys(weights, source)
    out: dict[str, int] = {}
    for sid in SUBSCALE_IDS:
        value = weights[sid]
        if (
            isinstance(value, bool)
            or not isinstance(value, int | np.integer | float)
            or not float(value).is_integer()
            or not 0 <= value <= len(SUBSCALE_IDS) - 1
        ):
            raise ValueError(
                f"{source}: subscale '{sid}': must be a whole number from 0 to "
                f"{len(SUBSCALE_IDS) - 1} (times chosen in the 15 comparisons), got {value!r}"
            )
        out[sid] = int(value)
    total = sum(out.values())
    if total != N_PAIRS:
        raise ValueError(
            f"{source}: must sum to {N_PAIRS} (one per pairwise comparison), got {total} "
            f"({_format(out)})"
        )
    # Landau (1953): the k lowest weights w_(1) <= ... <= w_(k) must sum to at least
    # k (k - 1) / 2, the comparisons those k subscales had among themselves.
    ordered = sorted(out.items(), key=lambda kv: kv[1])
    running = 0
    for k, (_, w) in enumerate(ordered, start=1):
        running += w
        if running < k * (k - 1) // 2:
            low = ", ".join(f"'{sid}'" for sid, _ in ordered[:k])
            raise ValueError(
                f"{source}: no set of pairwise choices gives these weights ({_format(out)}): "
                f"subscales {low} were compared with each other {k * (k - 1) // 2} times, "
                f"so their weights must sum to at least that, got {running}"
            )
    return out


def weights_from_choices(choices: Mapping[tuple[str, str] | str, str]) -> dict[str, int]:
    """Tally the 15 pairwise choices into weights.

    Parameters
    ----------
    choices : Mapping
        Each of the 15 pairs -> the chosen subscale id. A pair is a tuple
        ``(a, b)`` in either orientation or its :func:`pair_id` string.

    Returns
    -------
    dict[str, int]
        Subscale id -> times chosen (0..5), in scale order; the values sum to 15.

    Raises
    ------
    ValueError
        On an unknown subscale or malformed pair, a pair given twice, a missing
        pair, or a choice that is not one of its pair's two members.
    """
    source = "NASA-TLX pairwise choices"
    if not isinstance(choices, Mapping):
        raise ValueError(f"{source}: must be a mapping of pair to chosen subscale id")
    tally = dict.fromkeys(SUBSCALE_IDS, 0)
    seen: set[tuple[str, str]] = set()
    for key, chosen in choices.items():
        pair = _canonical_pair(key, source=source)
        if pair in seen:
            raise ValueError(f"{source}: pair {pair_id(*pair)!r} is given more than once")
        seen.add(pair)
        if chosen not in pair:
            raise ValueError(
                f"{source}: pair {pair_id(*pair)!r}: the choice must be {pair[0]!r} or "
                f"{pair[1]!r}, got {chosen!r}"
            )
        tally[chosen] += 1
    missing = [pair_id(*p) for p in PAIRS if p not in seen]
    if missing:
        raise ValueError(
            f"{source}: {len(missing)} of the {N_PAIRS} pairs missing: {', '.join(missing)}"
        )
    return tally


def score(ratings: Mapping[str, int], weights: Mapping[str, int] | None = None) -> TlxScore:
    """Raw and (with weights) weighted NASA-TLX workload.

    ``raw = mean(r_i)`` (the "RTLX", Hart 2006), ``adjusted_i = r_i * w_i`` and
    ``weighted = sum(adjusted_i) / 15`` over the six subscales i, with ratings r_i in
    0..100 and weights w_i = times chosen in the pairwise comparisons (Hart & Staveland
    1988; NASA-TLX manual, "Scoring").

    Parameters
    ----------
    ratings : Mapping[str, int]
        All six subscale ids -> rating, a multiple of 5 from 0 to 100.
    weights : Mapping[str, int], optional
        All six subscale ids -> weight (see :func:`weights_from_choices`).

    Returns
    -------
    TlxScore

    Raises
    ------
    ValueError
        On invalid ratings or weights, naming the subscale.

    Notes
    -----
    In R: ``rowMeans(ratings)`` and ``rowSums(ratings * weights) / 15``.
    """
    r = validate_ratings(ratings)
    raw = sum(r.values()) / len(r)
    if weights is None:
        return TlxScore(raw=raw, weighted=None, ratings=r, weights=None, adjusted=None)
    w = validate_weights(weights)
    adjusted = {sid: r[sid] * w[sid] for sid in SUBSCALE_IDS}
    weighted = sum(adjusted.values()) / N_PAIRS
    return TlxScore(raw=raw, weighted=weighted, ratings=r, weights=w, adjusted=adjusted)


def _check_keys(values: Mapping[str, object], source: str) -> None:
    unknown = [k for k in values if k not in SUBSCALE_IDS]
    if unknown:
        raise ValueError(
            f"{source}: unknown subscale {unknown[0]!r}; allowed: {', '.join(SUBSCALE_IDS)}"
        )
    missing = [sid for sid in SUBSCALE_IDS if sid not in values]
    if missing:
        raise ValueError(
            f"{source}: missing subscale {', '.join(repr(m) for m in missing)}; all six "
            f"are required: {', '.join(SUBSCALE_IDS)}"
        )


def _canonical_pair(key: object, *, source: str) -> tuple[str, str]:
    """A pair key (tuple in either orientation, or a pair id) in canonical orientation."""
    if isinstance(key, str):
        parts = tuple(key.split("_vs_"))
    elif isinstance(key, tuple | list):
        parts = tuple(key)
    else:
        parts = ()
    if len(parts) != 2 or parts[0] == parts[1] or not all(p in SUBSCALE_IDS for p in parts):
        raise ValueError(
            f"{source}: {key!r} is not a pair of two different subscales; subscales: "
            f"{', '.join(SUBSCALE_IDS)}"
        )
    a, b = parts
    return (a, b) if SUBSCALE_IDS.index(a) < SUBSCALE_IDS.index(b) else (b, a)


def _format(values: Mapping[str, int]) -> str:
    return ", ".join(f"{k}={v}" for k, v in values.items())
