"""A secret in every form a server, a proxy or a log can echo it back in, so that none of them is shown.

Why: the RockBLOCK password goes out form-encoded. A gateway or proxy that echoes the request in an
error page sends it back percent-encoded (`&` → `%26`, space → `+`, `é` → `%C3%A9`), and redacting only
the literal password left those readable in the terminal, the command's detail, the audit log and
History. Every encoding below is replaced, longest first, so one form never hides a longer one.
"""

from __future__ import annotations

import base64
import html
import json
import unicodedata
from urllib.parse import quote, quote_plus

MASK = "***"


def secret_forms(secret: str, username: str = "") -> set[str]:
    """The secret as sent and as echoed: raw and in each Unicode normal form, percent-encoded (either case,
    `+` or `%20` for space, `/` kept or escaped, and encoded twice), HTML escaped (named, and numeric
    entities in decimal and hex), JSON escaped, as a Python bytes or str repr, and base64 (alone, as HTTP
    Basic `user:secret`, and inside a base64-encoded request body at any alignment)."""
    if not secret:
        return set()
    texts = {unicodedata.normalize(form, secret) for form in ("NFC", "NFD", "NFKC", "NFKD")} | {secret}
    forms: set[str] = set()
    for text in texts:
        forms |= {text, html.escape(text), json.dumps(text, ensure_ascii=True)[1:-1],
                  json.dumps(text, ensure_ascii=False)[1:-1], repr(text)[1:-1],
                  repr(text.encode("utf-8"))[2:-1], *_numeric_entities(text)}  # fmt: skip
        percent = {quote(text, safe=""), quote_plus(text, safe=""), quote(text), quote_plus(text, safe="/")}
        percent |= {quote(once, safe="") for once in percent}  # encoded twice: `%` → `%25`
        for encoded in percent:
            forms |= {encoded, encoded.lower(), _upper_escapes(encoded)}
        for raw in (text, quote_plus(text, safe=""), f"{username}:{text}" if username else None):
            if raw is not None:
                token = base64.b64encode(raw.encode("utf-8")).decode("ascii")
                forms |= {token, token.rstrip("="), *_base64_inside(raw.encode("utf-8"))}
    return {form for form in forms if form}


def _numeric_entities(text: str) -> set[str]:
    """``&#112;`` and ``&#x70;`` for every character, or only for those an escaper would touch."""
    forms = set()
    for every in (True, False):
        for pattern in ("&#{:d};", "&#x{:x};", "&#x{:X};"):
            forms.add("".join(pattern.format(ord(c)) if every or not c.isalnum() else c for c in text))
    return forms


def _base64_inside(raw: bytes) -> set[str]:
    """The part of a base64 text that only ``raw``'s bytes decide, for each of the three offsets it can
    have inside a longer encoded body (a gateway that echoes the request base64-encoded)."""
    forms = set()
    for offset in range(3):
        token = base64.b64encode(bytes(offset) + raw).decode("ascii")
        first = -(-offset // 3)  # the first 3-byte group wholly inside raw
        last = (offset + len(raw)) // 3  # one past the last whole group
        if last - first >= 2:  # a shorter run would match unrelated text
            forms.add(token[4 * first : 4 * last])
    return forms


def _upper_escapes(text: str) -> str:
    """`%2b` → `%2B`: percent escapes in upper case, the rest as it is."""
    parts = text.split("%")
    return parts[0] + "".join("%" + p[:2].upper() + p[2:] for p in parts[1:])


def redact(text: str, forms: set[str]) -> str:
    for form in sorted(forms, key=len, reverse=True):
        text = text.replace(form, MASK)
    return text
