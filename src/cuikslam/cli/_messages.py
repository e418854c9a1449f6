"""The command line's words for the library's messages: the same message, naming flags.

The library words a :class:`~cuikslam.messages.Message` as the Python API spells its
options (``raise max_hypotheses``); :func:`worded` gives the command line's wording of
the same code and data (``raise --max-hypotheses``). A message without a wording here is
printed as the library words it.
"""

from __future__ import annotations

from cuikslam.messages import Message

__all__ = ["WORDING", "worded"]

WORDING: dict[str, str] = {
    "time_bound": (
        "the wall-clock cap (--time-budget) stopped a stage before its work budget: this "
        "result depends on how fast the machine ran, and may differ from run to run"
    ),
    "unreported_survivors": (
        "{survivors} survivors were not kept for the report; raise --max-hypotheses"
    ),
    "survivors_beyond_report": (
        "{survivors} hypotheses survived; the {reported} best-ranked are reported (raise "
        "--max-hypotheses to see more)"
    ),
    "reported_survivors_refuted": (
        "the {refuted} best-ranked survivors were proven impossible after the search; the "
        "other {others} were not kept for the report (raise --max-hypotheses): the log is "
        "NOT proven inconsistent"
    ),
    "strengthen_limit": (
        "{reported} hypotheses are reported: the '{level}' level was applied to one of them "
        "only, the first in rank order (to all when at most {limit}; raise "
        "--strengthen-limit); the others' boxes are at least hull-consistent"
    ),
    "truth_nothing_found": (
        "truth check: the search stopped on its budget before finding a hypothesis "
        "(incomplete, not a refutation; raise --work-budget)"
    ),
    "truth_unreported": (
        "truth check: the true correspondence is not among the {reported} reported of "
        "{survivors} survivors (raise --max-hypotheses to see it)"
    ),
    "truth_search_incomplete": (
        "truth check: the true correspondence is not among the survivors found before the "
        "search stopped on its budget (the search was incomplete; raise --work-budget)"
    ),
    "outliers_declared": (
        "the log declares outliers ({declared}) and {proven} were proven: the boxes are "
        "guaranteed only if the declaration holds (`cuikslam calibrate check LOG --truth "
        "TRUTH` says whether it does)"
    ),
    "no_truth_at_start": "no Vicon pose of robot {robot} at the window start: move --start",
    "keyframe_beyond_calibration": (
        "keyframes of {keyframe} samples, but the bounds were calibrated on stretches of at "
        "most {max_samples} (calibrate with --keyframe {keyframe})"
    ),
}
"""Message code -> the command line's wording, a format string of the message's data."""


def worded(message: str) -> str:
    """``message`` as the command line says it (naming flags where the library names
    options).

    Examples
    --------
    >>> worded(Message("unreported_survivors", "3 ...; raise max_hypotheses", survivors=3))
    '3 survivors were not kept for the report; raise --max-hypotheses'
    >>> worded("a plain message")
    'a plain message'
    """
    if isinstance(message, Message) and message.code in WORDING:
        return WORDING[message.code].format(**message.data)
    return str(message)
