"""Text from the network, made safe to show: keys, type names, participant names and ids reach
alarm texts, tables, log lines and terminals, and any peer may send a terminal's escape
sequences (clear screen, set title) in them.

`visible` shows every character Python does not call printable — C0 and C1 controls, DEL,
format characters such as bidirectional overrides, lone surrogates — as an escape (`\\x1b`,
`\\u202e`), and a backslash as `\\\\` so that an escape shown cannot be forged by sending its
text. Printable text is returned unchanged and cheaply (one `isprintable` call), so ids that
passed `keys.is_id` cost nothing.
"""

from __future__ import annotations

ELLIPSIS = "…"


def visible(text: object, limit: int | None = None) -> str:
    """`text` with its unprintable characters escaped; cut to `limit` characters (before
    escaping, then marked with …) when given."""
    s = text if type(text) is str else str(text)
    cut = limit is not None and len(s) > limit
    if cut:
        s = s[:limit]
    if not s.isprintable() or "\\" in s:
        s = "".join(_escape(c) for c in s)
    return s + ELLIPSIS if cut else s


def _escape(c: str) -> str:
    if c == "\\":
        return "\\\\"
    if c.isprintable():
        return c
    n = ord(c)
    if n <= 0xFF:
        return f"\\x{n:02x}"
    if n <= 0xFFFF:
        return f"\\u{n:04x}"
    return f"\\U{n:08x}"
