"""Named observation layouts: an observation's parts by name, each a slice of its columns.

An env lists its observation's parts in order, ``(name, size)`` each
(:data:`ObservationParts`), and exposes them as ``env.unwrapped.observation_layout``, a
mapping name -> slice (:func:`observation_layout`), so that a consumer reads
``obs[layout["pen_position"]]``, never ``obs[24:27]``.
"""

from __future__ import annotations

#: An observation's parts in order: ``(name, size)`` each.
ObservationParts = tuple[tuple[str, int], ...]


def observation_layout(parts: ObservationParts) -> dict[str, slice]:
    """Names to slices of an observation made of ``parts`` (name, size) in order.

    Raises:
        ValueError: a name twice, or a size < 1.
    """
    out: dict[str, slice] = {}
    start = 0
    for name, size in parts:
        if name in out:
            raise ValueError(f"observation part {name!r} appears twice in {parts}")
        if size < 1:
            raise ValueError(f"observation part {name!r} has size {size}, must be >= 1")
        out[name] = slice(start, start + size)
        start += size
    return out


def layout_size(parts: ObservationParts) -> int:
    """The number of columns of an observation made of ``parts``."""
    return sum(size for _, size in parts)
