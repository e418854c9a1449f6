"""Fast JSON where it pays: orjson when it is installed (``pip install cuikslam[fast]``),
the standard library otherwise, with the same values either way.

Reading a log line: :func:`loads_object` returns a decoded object only when it is sure
the strict reader (:mod:`cuikslam.log.reader`) would decode the same object, and None
otherwise, so that the strict reader runs and words the error. Writing a result:
:func:`dumps` writes the same values as :func:`json.dumps` (floats as their shortest
repr, which reads back as the same double).
"""

from __future__ import annotations

import json
import re
from typing import Any

try:
    import orjson
except ImportError:  # an optional extra
    orjson = None

__all__ = ["HAVE_ORJSON", "dumps", "loads_object"]

HAVE_ORJSON = orjson is not None

_KEY = re.compile(r'"\s*:')
"""Where a key can end: every key of a JSON object matches (a string value may too)."""
_LONG_DIGITS = re.compile(r"\d{19}")
"""A digit run orjson might read otherwise than the standard library (it turns integers
beyond 64 bits into floats): such lines take the strict path."""


def loads_object(text: str) -> dict[str, Any] | None:
    """The JSON object ``text`` holds, or None when the fast path cannot vouch for it.

    None when orjson is missing, refuses the text (malformed JSON, NaN), the text has a
    run of 19 digits or more (orjson reads integers beyond 64 bits as floats), or it
    decodes to something other than an object of unique keys: orjson keeps the last of
    two equal keys silently, so an object is returned only when it has as many keys as
    the text has places where a key can end (a nested object or a string value holding
    ``":`` sends the line to the strict path too).
    """
    if orjson is None or _LONG_DIGITS.search(text):
        return None
    try:
        value = orjson.loads(text)
    except orjson.JSONDecodeError:
        return None
    if type(value) is not dict or len(_KEY.findall(text)) != len(value):
        return None
    return value


def dumps(document: Any, *, finite: bool = False) -> str:
    """``document`` as indented JSON text.

    Parameters
    ----------
    document : Any
        Plain JSON-ready objects.
    finite : bool
        The caller vouches that no float in ``document`` is NaN or infinite; only then is
        orjson used (it would write them as null, where the standard library writes
        ``NaN`` and ``Infinity``).
    """
    if orjson is not None and finite:
        try:
            return orjson.dumps(document, option=orjson.OPT_INDENT_2).decode("utf-8")
        except TypeError:  # e.g. an integer beyond 64 bits: the standard library writes it
            pass
    return json.dumps(document, indent=1)
