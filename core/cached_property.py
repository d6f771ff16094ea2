"""A property computed on first use and kept on the instance, with no lock held while it is computed.

Python 3.11's :class:`functools.cached_property` computes under one lock per property *of the class*
(every instance's computation of it waits for any other's). A process forked while a thread of it
computes such a property (a pool thread preparing or solving a gap, :mod:`core.sequence_gaps_ahead`;
a pipeline's worker processes forked while a sequence runs) gets that lock held by a thread that does
not exist in the child: the child's first computation of the property on any instance waits for ever
(docs/inbetween-measurements.md, *A forked child stuck on a lock of the parent's threads*). The
lock also made two threads computing the property on two different gaps wait for each other. Python
3.12 dropped it (a value two threads compute at once is computed twice, the last stored); this is the
same property on 3.11. Every property kept so in the core depends on its instance alone, so two threads computing it at once compute the same value.
"""

from __future__ import annotations

import functools
import sys

__all__ = ["cached_property"]

if sys.version_info >= (3, 12):
    cached_property = functools.cached_property  # no lock since 3.12
else:
    _MISSING = object()

    class cached_property(functools.cached_property):  # the name functools gives it
        """:class:`functools.cached_property` without its per-class lock (as in Python 3.12)."""

        def __get__(self, instance, owner=None):
            if instance is None:
                return self
            if self.attrname is None:
                raise TypeError("Cannot use cached_property instance without calling __set_name__ on it.")
            cache = instance.__dict__
            value = cache.get(self.attrname, _MISSING)
            if value is _MISSING:
                value = self.func(instance)
                cache[self.attrname] = value
            return value
