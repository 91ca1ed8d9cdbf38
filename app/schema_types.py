"""Field types of requests: times and dates as ISO 8601 text only, and errors that always encode.

Pydantic reads a number (or a string of digits) as seconds since 1970 where a datetime is
expected, so `"flown_at": 0` or `?as_of=0` became 1970-01-01; here such values are refused with
a 422 naming the field.  Request models also refuse NaN and infinities (`allow_inf_nan=False`
in their config); their error lists carry the value sent, which JSON cannot encode when it is
not finite, so encodable() writes those as text.

A 422 quotes what was sent (each error's `input`) cut to a prefix (echoed()): a 10 MB field came
back whole.

Numbers and booleans of request bodies are strict (Integer, Number, Boolean): pydantic's lax mode
read `{"seed": false}` as seed 0, `"detected": 1` as true and `"epochs": "5"` as 5; JSON has
its own true, false and numbers, and only those are taken (an integer is a Number too, and a
number without a fraction, 26.0, an Integer, as JSON Schema reads them).
"""

from __future__ import annotations

import math
import re
from datetime import date, datetime
from typing import Annotated, Any

from pydantic import BeforeValidator, Strict

_ISO_DATE = re.compile(r"\d{4}-\d{2}-\d{2}")
_ISO_TIME = re.compile(r"\d{4}-\d{2}-\d{2}([T ]\d{2}:\d{2}.*)?")


# What a 422 quotes of one value sent: text to this many characters, lists and objects to this
# many items (recursively), each cut saying how long the whole was.
MAX_ECHOED_CHARS = 200
MAX_ECHOED_ITEMS = 10


def echoed(value: Any) -> Any:
    """value as an error quotes it: a prefix of long text, the first items of long lists and
    objects (keys quoted as text is), each cut marked with the whole's length."""
    if isinstance(value, str | bytes):
        text = value if isinstance(value, str) else value.decode("utf-8", "replace")
        if len(text) <= MAX_ECHOED_CHARS:
            return value
        return f"{text[:MAX_ECHOED_CHARS]}… ({len(text)} characters)"
    if isinstance(value, list | tuple):
        items = [echoed(v) for v in value[:MAX_ECHOED_ITEMS]]
        if len(value) > MAX_ECHOED_ITEMS:
            items.append(f"… ({len(value)} items)")
        return items
    if isinstance(value, dict):
        kept = list(value.items())[:MAX_ECHOED_ITEMS]
        quoted = {echoed(str(k)): echoed(v) for k, v in kept}
        if len(value) > MAX_ECHOED_ITEMS:
            quoted["…"] = f"{len(value)} keys"
        return quoted
    return value


def _iso_time_text(value: Any) -> Any:
    if isinstance(value, datetime) or (isinstance(value, str) and _ISO_TIME.fullmatch(value)):
        return value
    raise ValueError(
        f"must be an ISO 8601 time such as 2025-01-05T06:00:00Z (not a number), "
        f"got {echoed(value)!r}"
    )


def _iso_date_text(value: Any) -> Any:
    if isinstance(value, date) or (isinstance(value, str) and _ISO_DATE.fullmatch(value)):
        return value
    raise ValueError(
        f"must be an ISO 8601 date such as 2025-01-05 (not a number), got {echoed(value)!r}"
    )


def _whole_number(value: Any) -> Any:
    """A JSON number without a fraction (26.0) as the integer it is, as JSON Schema's `integer`
    takes it (a schema-valid request was refused); a fraction, a boolean or text is left to
    Strict to refuse."""
    if isinstance(value, float) and value.is_integer():
        return int(value)
    return value


IsoDateTime = Annotated[datetime, BeforeValidator(_iso_time_text)]
IsoDate = Annotated[date, BeforeValidator(_iso_date_text)]
# An integer field with bounds: Annotated[int, Strict(), Field(ge=..., le=...), WholeNumber].  The
# bounds go before WholeNumber: put on top of it (`Annotated[Integer, Field(ge=...)] | None`),
# pydantic wrote them into the JSON schema as unknown `ge`/`le` keys, which no client or fuzzer
# reads as bounds.
WholeNumber = BeforeValidator(_whole_number)
Integer = Annotated[int, Strict(), WholeNumber]
Number = Annotated[float, Strict()]
Boolean = Annotated[bool, Strict()]


def encodable(value: Any) -> Any:
    """value with every float that is not finite (NaN, inf) replaced by its text, recursively
    through dicts, lists and tuples: JSON has no such numbers."""
    if isinstance(value, float) and not math.isfinite(value):
        return str(value)
    if isinstance(value, dict):
        return {k: encodable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [encodable(v) for v in value]
    return value


def never_null(schema: dict[str, Any]) -> None:
    """A field's JSON schema without its null branch (json_schema_extra): a field a request may
    leave out but not send as null (a correction's kept fields) is stated as such, so no
    schema-valid request is refused for its null."""
    options = schema.get("anyOf")
    if not options:
        return
    kept = [option for option in options if option.get("type") != "null"]
    if len(kept) == 1:
        del schema["anyOf"]
        schema.update(kept[0])
