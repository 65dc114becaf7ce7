"""Byte-level mutations of text instrument files for the readers' hypothesis tests."""

from __future__ import annotations

from hypothesis import strategies as st


def mutation_ops(alphabet: bytes) -> st.SearchStrategy:
    """One to four ``(op, where, byte)``: replace, delete or insert ``byte`` at the relative
    position ``where`` (0-1) of the file, or truncate it there; bytes from ``alphabet``
    (the separators, digits and markers of the format)."""
    return st.lists(
        st.tuples(
            st.sampled_from(["replace", "delete", "insert", "truncate"]),
            st.floats(0, 1, allow_nan=False),
            st.sampled_from(list(alphabet)),
        ),
        min_size=1,
        max_size=4,
    )


def mutated(data: bytes, ops: list[tuple[str, float, int]]) -> bytes:
    """``data`` with the operations of :func:`mutation_ops` applied in order."""
    out = bytearray(data)
    for op, where, byte in ops:
        i = min(int(where * len(out)), max(len(out) - 1, 0))
        if op == "replace" and out:
            out[i] = byte
        elif op == "delete" and out:
            del out[i]
        elif op == "insert":
            out.insert(i, byte)
        else:
            del out[i:]
    return bytes(out)
