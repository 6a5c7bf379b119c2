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
from urllib.parse import quote, quote_plus

MASK = "***"


def secret_forms(secret: str, username: str = "") -> set[str]:
    """The secret as sent and as echoed: raw, percent-encoded (either case, `+` or `%20` for space), HTML
    and JSON escaped, and base64 (alone, and as HTTP Basic `user:secret`)."""
    if not secret:
        return set()
    forms = {secret, html.escape(secret), json.dumps(secret, ensure_ascii=True)[1:-1],
             json.dumps(secret, ensure_ascii=False)[1:-1]}  # fmt: skip
    for encoded in (quote(secret, safe=""), quote_plus(secret, safe="")):
        forms |= {encoded, encoded.lower(), _upper_escapes(encoded)}
    for raw in (secret, f"{username}:{secret}" if username else None):
        if raw is not None:
            token = base64.b64encode(raw.encode("utf-8")).decode("ascii")
            forms |= {token, token.rstrip("=")}
    return {form for form in forms if form}


def _upper_escapes(text: str) -> str:
    """`%2b` → `%2B`: percent escapes in upper case, the rest as it is."""
    parts = text.split("%")
    return parts[0] + "".join("%" + p[:2].upper() + p[2:] for p in parts[1:])


def redact(text: str, forms: set[str]) -> str:
    for form in sorted(forms, key=len, reverse=True):
        text = text.replace(form, MASK)
    return text
