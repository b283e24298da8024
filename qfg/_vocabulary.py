"""One keyword, ``method=``, chooses a variant everywhere (CHANGELOG.md, 0.6.0).

The keywords and values it replaced are not aliases: passing one raises an error whose one line
names its replacement, so code written against 0.5 fails where it calls, not with another answer.
"""

from __future__ import annotations

import functools

__all__ = ["check_method", "renamed_keywords"]


def renamed_keywords(**renamed):
    """Decorator: a call passing an old keyword (``old="new"`` pairs) raises a ``TypeError``
    naming the new one. The signature is the wrapped function's (``inspect.signature``).

    >>> @renamed_keywords(rule="method")
    ... def f(method="a"):
    ...     return method
    >>> f(rule="a")
    Traceback (most recent call last):
    ...
    TypeError: f: the keyword rule= is now method= (CHANGELOG.md, 0.6.0)
    """
    def deco(func):
        @functools.wraps(func)
        def wrapper(*args, **kwargs):
            for old, new in renamed.items():
                if old in kwargs:
                    raise TypeError(f"{func.__name__}: the keyword {old}= is now {new}= "
                                    "(CHANGELOG.md, 0.6.0)")
            return func(*args, **kwargs)
        return wrapper
    return deco


def check_method(method, allowed: tuple, renamed: dict | None = None, name: str = "method"):
    """``method`` if it is one of ``allowed``; an old value (a key of ``renamed``) raises a
    ``ValueError`` naming its new value, anything else one listing ``allowed``.

    >>> check_method("pooled", ("best", "pooled"), {"mean": "pooled"})
    'pooled'
    >>> check_method("mean", ("best", "pooled"), {"mean": "pooled"})
    Traceback (most recent call last):
    ...
    ValueError: method: 'mean' is now 'pooled' (CHANGELOG.md, 0.6.0)
    """
    if isinstance(method, str) and method in allowed:
        return method
    if isinstance(method, str) and renamed and method in renamed:
        raise ValueError(f"{name}: {method!r} is now {renamed[method]!r} (CHANGELOG.md, 0.6.0)")
    raise ValueError(f"{name}: expected one of {tuple(allowed)}, got {method!r}")
