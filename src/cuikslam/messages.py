"""Messages of the library: the words of the library, with a code and data the CLI words.

A solve says what it found out in ``Solution.messages``, a truth check in its verdict's
lines, a reader in its :class:`~cuikslam.errors.InputFileError`. Each is a
:class:`Message`: a ``str`` (so it prints, joins and is written to the result JSON as
before) in the library's words, which name options as the Python API spells them
(``time_budget``, ``max_hypotheses``), never as command-line flags; its ``code`` and
``data`` let the command line say the same in its own words, naming its flags
(``cuikslam.cli._messages``). A message without a code is worded the same everywhere.

Examples
--------
>>> message = Message("time_bound", "the wall-clock cap (time_budget) stopped a stage")
>>> message.code, message.upper()
('time_bound', 'THE WALL-CLOCK CAP (TIME_BUDGET) STOPPED A STAGE')
>>> Message("max_hypotheses", "3 survivors were not kept", left=3).data
{'left': 3}
"""

from __future__ import annotations

from typing import Any

__all__ = ["Message"]


class Message(str):
    """A message: its text (the ``str`` itself), a ``code`` and the ``data`` it speaks of.

    Parameters
    ----------
    code : str
        What the message says, as a short name the command line looks its wording up by.
    text : str
        The message in the library's words.
    **data
        The values the message speaks of (counts, option values), for another wording.
    """

    code: str
    data: dict[str, Any]

    def __new__(cls, code: str, text: str, **data: Any) -> Message:
        message = super().__new__(cls, text)
        message.code = code
        message.data = data
        return message

    def __reduce__(self) -> tuple[Any, ...]:
        return (_message, (self.code, str(self), self.data))


def _message(code: str, text: str, data: dict[str, Any]) -> Message:
    """A message again (unpickled, e.g. from a worker of a cluster)."""
    return Message(code, text, **data)
