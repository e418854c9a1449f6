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
from typing import Any

try:
    import orjson
except ImportError:  # an optional extra
    orjson = None

__all__ = ["HAVE_ORJSON", "dumps", "loads_object"]

HAVE_ORJSON = orjson is not None

_BIG = 2.0**63
"""orjson reads an integer beyond 64 bits as a float: a float this large may have been one."""


def loads_object(text: str) -> dict[str, Any] | None:
    """The JSON object ``text`` holds, or None when the fast path cannot vouch for it.

    None when orjson is missing or refuses the text (malformed JSON, NaN), and unless
    the text decodes to an object whose values are scalars or lists of scalars, with no
    float of magnitude 2**63 or more (orjson reads larger integers as floats), and with
    as many ``:`` in the text as keys in the object: orjson keeps the last of two equal
    keys silently, and every key is followed by a colon, so this equality rules out a
    repeated key (a colon inside a string only sends the line to the strict path).
    """
    if orjson is None:
        return None
    try:
        value = orjson.loads(text)
    except orjson.JSONDecodeError:
        return None
    if type(value) is not dict or text.count(":") != len(value):
        return None
    for item in value.values():
        if type(item) is list:
            for element in item:
                if type(element) in (list, dict) or (
                    type(element) is float and not -_BIG < element < _BIG
                ):
                    return None
        elif type(item) is dict or (type(item) is float and not -_BIG < item < _BIG):
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
