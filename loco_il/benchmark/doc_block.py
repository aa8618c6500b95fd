"""Generated blocks inside hand-written documents (the README's leaderboard, RESULTS.md's cost model check).

A block sits between two marker lines named after it,

    <!-- NAME -->
    ...generated...
    <!-- /NAME -->

so a command can rewrite it and a test can check that the committed text is what the command gives now.
"""
from __future__ import annotations

from typing import Sequence


class MarkerError(ValueError):
    """A document without (or with broken) markers: one line naming the markers to add."""


def markers(name: str) -> tuple[str, str]:
    return f"<!-- {name} -->", f"<!-- /{name} -->"


def replace_block(text: str, name: str, block: Sequence[str], where: str = "the document") -> str:
    """`text` with the lines between the two `name` marker lines replaced by `block`."""
    start, end = markers(name)
    i, j = text.find(start), text.find(end)
    if i < 0 or j < 0 or j < i:
        raise MarkerError(f"{where} has no '{start}' ... '{end}' block; add the two marker lines, in that order, "
                          "where the generated text goes")
    return text[:i + len(start)] + "\n" + "\n".join(block) + "\n" + text[j:]


__all__ = ["MarkerError", "markers", "replace_block"]
