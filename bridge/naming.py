"""Names within Blender's length limit, the end that matters (a factor, a number) kept whole, and
free names (``.001``, ``.002``, ...) that never cut that end.
"""

from __future__ import annotations

MAX_NAME_LENGTH = 63  # bytes (UTF-8) in a Blender ID or shape key name


def shorten(text: str, limit: int) -> str:
    """``text`` within ``limit`` bytes (UTF-8), cut short with a final "…" if it is longer."""
    encoded = text.encode()
    if len(encoded) <= limit:
        return text
    ellipsis = "\u2026"
    return encoded[:max(limit - len(ellipsis.encode()), 0)].decode(errors="ignore") + ellipsis


def fit_name(head: str, tail: str = "") -> str:
    """``head + tail`` within Blender's name length: ``head`` (e.g. a key or object name) is
    shortened so that ``tail`` (the factor, the reference, a number) is always kept whole."""
    return shorten(head, MAX_NAME_LENGTH - len(tail.encode())) + tail


def unique_name(head: str, tail: str, taken) -> str:
    """``fit_name(head, tail)``, or with ``.001``, ``.002``, ... appended if that name is taken.

    Blender's own renaming cuts the end of a long name to fit its number (losing a factor) and
    reads a name ending in ``0.50`` as already numbered (``0.051``); this never does either."""
    candidate = fit_name(head, tail)
    number = 0
    while candidate in taken:
        number += 1
        candidate = fit_name(head, f"{tail}.{number:03d}")
    return candidate
