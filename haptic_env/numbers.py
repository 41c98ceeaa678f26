"""What a setting accepts as a real number, a whole number, a yes/no flag, a range or a list of distinct values:
the checks behind the configs' fields.

``np.isfinite`` alone is not that check: it raises numpy's own ``TypeError`` (naming neither the field nor the
value) for a string or for a Python ``int`` beyond int64, and it takes ``True`` as 1. The configs call
:func:`finite_number` first and then raise their own ``ValueError`` naming the field and the value.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["finite_number", "whole_number", "flag", "items", "positive_range", "positive_number", "whole_at_least",
           "checked_flag", "check_whole_fields", "check_flag_fields", "repeated"]


def repeated(values) -> list:
    """The values that ``values`` holds more than once, sorted (empty: each once). A seed given twice would count its
    episodes or runs twice (a narrower spread over the same evidence); a name twice would pool two agents."""
    values = list(values)
    return sorted({v for i, v in enumerate(values) if v in values[:i]})


def finite_number(value) -> float | None:
    """``value`` as a float if it is a finite real number (``int``, ``float`` or a numpy scalar of either, of any
    size, not ``bool``), else None (strings, ``bool``, arrays, NaN, +-inf, and ints too large for a float)."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
        return None
    try:
        f = float(value)
    except OverflowError:
        return None
    return f if math.isfinite(f) else None


def whole_number(value) -> int | None:
    """``value`` as an int if it is a whole number (``int`` or a numpy integer scalar, not ``bool``), else None (floats
    such as ``4.0``, strings, ``bool``, None, arrays). The caller checks the bounds and raises its own ``ValueError``
    naming the field, as with :func:`finite_number`."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        return None
    return int(value)


def flag(value) -> bool | None:
    """``value`` as a bool if it is ``bool`` or a numpy bool scalar, else None (``0``/``1``, strings such as
    ``"false"``, None): a yes/no setting is never read by truthiness."""
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    return None


def items(value) -> tuple | None:
    """``value``'s elements as a tuple (of a tuple, a list, an array), or None where it has none (a number, None): a
    setting that wants a sequence then raises its own ``ValueError``, not Python's "'float' object is not iterable"."""
    try:
        return tuple(value)
    except TypeError:
        return None


def positive_number(value, name: str) -> float:
    """``value`` as a float if it is a :func:`finite_number` ``> 0``, else a ``ValueError`` "``<name>`` must be a finite
    number > 0". A plain positive float returns at once (the per-step callers pass one)."""
    if type(value) is float and 0.0 < value < math.inf:
        return value
    f = finite_number(value)
    if f is None or not f > 0.0:
        raise ValueError(f"{name} must be a finite number > 0, got {value!r}")
    return f


def whole_at_least(value, lo: int, name: str) -> int:
    """``value`` as an int if it is a :func:`whole_number` ``>= lo``, else a ``ValueError`` "``<name>`` must be an int
    >= ``lo``" (2.5 is not cut to 2, nor True taken as 1)."""
    v = whole_number(value)
    if v is None or v < lo:
        raise ValueError(f"{name} must be an int >= {lo}, got {value!r}")
    return v


def checked_flag(value, name: str, says: str = "a bool") -> bool:
    """``value`` as a bool if it is a :func:`flag`, else a ``ValueError`` "``<name>`` must be ``<says>``"
    (``bool("no")`` is True: a yes/no setting is never read by truthiness)."""
    b = flag(value)
    if b is None:
        raise ValueError(f"{name} must be {says}, got {value!r}")
    return b


def check_whole_fields(obj, fields) -> None:
    """Check and store whole-number fields of a (frozen) settings dataclass: for each ``(name, lo)`` of ``fields``,
    ``obj.<name>`` must be a :func:`whole_number` ``>= lo`` (a ``ValueError`` naming it otherwise), and is stored back
    as the Python int (a numpy int keys as the int it stands for)."""
    for name, lo in fields:
        object.__setattr__(obj, name, whole_at_least(getattr(obj, name), lo, name))


def check_flag_fields(obj, names, says: str = "a bool") -> None:
    """Check and store yes/no fields of a (frozen) settings dataclass: each ``obj.<name>`` must be a :func:`flag`
    (a ``ValueError`` "``<name>`` must be ``<says>``" otherwise: ``bool("no")`` is True), stored back as the Python
    bool."""
    for name in names:
        object.__setattr__(obj, name, checked_flag(getattr(obj, name), name, says))


def positive_range(value, name: str) -> tuple[float, float]:
    """``value`` as ``(lo, hi)`` floats with ``0 < lo <= hi``, both finite real numbers (:func:`finite_number`); else a
    ``ValueError`` naming ``name`` and the value (a scalar, a string, a pair of another length, NaN or inf, ...)."""
    pair = items(value) or ()
    lo_hi = tuple(finite_number(v) for v in pair) if len(pair) == 2 else (None, None)
    if None in lo_hi or not 0.0 < lo_hi[0] <= lo_hi[1]:
        raise ValueError(f"{name} must be (lo, hi) with 0 < lo <= hi, got {value!r}")
    return lo_hi
