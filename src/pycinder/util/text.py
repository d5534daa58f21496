"""Counts written for people: one helper, so that no message says "1 bodies"."""

from __future__ import annotations

import re


def plural(n: int, word: str, many: str | None = None) -> str:
    """``n`` and ``word``, singular or plural: ``"1 body"``, ``"2 bodies"``, ``"1,000 pairs"``.

    Parameters
    ----------
    n : int
        How many (written with thousands separators).
    word : str
        The singular (``"body"``, ``"candidate pair"``).
    many : str, optional
        The plural, where it is not ``word`` + ``"s"`` (or ``"ies"`` for a consonant + ``"y"``).
    """
    if n == 1:
        return f"1 {word}"
    if many is None:
        many = word[:-1] + "ies" if re.search(r"[^aeiou]y$", word) else word + "s"
    return f"{n:,} {many}"
