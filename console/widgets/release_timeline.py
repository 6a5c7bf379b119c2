"""The release-window sweep as text: one glyph per candidate release time over a time axis.

Plain characters with words beside them, so it reads at 80×24, without colour and over a slow SSH
link: ✓ go, ✗ no-go, ? no landing (the descent left the weather), ▲ the recommended time, ^ the cursor.
"""

from __future__ import annotations

from datetime import datetime

from drs_link.ops import ReleaseCandidate, ReleaseWindow

GO, NO_GO, NO_LANDING = "✓", "✗", "?"
TICK_EVERY = 6


def _hhmm(moment: datetime) -> str:
    return f"{moment:%H:%M}"


def glyph(candidate: ReleaseCandidate) -> str:
    if not candidate.landed:
        return NO_LANDING
    return GO if candidate.go else NO_GO


def default_cursor(window: ReleaseWindow) -> int:
    """The first no-go (what the operator must understand first), else the recommended time."""
    candidates = window.candidates
    first_no_go = next((i for i, c in enumerate(candidates) if not c.go), None)
    if first_no_go is not None:
        return first_no_go
    return window.recommended or 0


def render_timeline(
    window: ReleaseWindow | None, cursor: int, age_text: str, indent: str = "  ", missing: str = "computing"
) -> str:
    """``missing`` says why there is no window yet (no weather, no position, released)."""
    if window is None:
        return f"Release window: {missing}"
    candidates = window.candidates
    if not candidates:
        return "Release window: no candidate release times"
    cursor = max(0, min(cursor, len(candidates) - 1))
    recommended = window.recommended
    step = window.every_minutes
    go = sum(c.go for c in candidates)
    best = "NO-GO window" if recommended is None else f"recommended {_hhmm(candidates[recommended].time)}Z"
    head = (
        f"Release window {_hhmm(candidates[0].time)}–{_hhmm(candidates[-1].time)}Z every {step:g} min:"
        f" {go}/{len(candidates)} go, {best}"
    )
    glyphs = "".join(glyph(c) for c in candidates)
    marks = [" "] * len(candidates)
    if recommended is not None:
        marks[recommended] = "▲"
    marks[cursor] = "^" if cursor != recommended else "▲"
    axis = ""
    for index in range(0, len(candidates), TICK_EVERY):
        axis = axis.ljust(index) + _hhmm(candidates[index].time)
    at = candidates[cursor]
    if at.go:
        detail = "go"
    else:
        detail = "no-go: " + ("; ".join(at.reasons) or "no reason given")
    lines = [
        head,
        indent + glyphs,
        indent + "".join(marks).rstrip(),
        indent + axis,
        f"{indent}at {_hhmm(at.time)}Z {glyph(at)} {detail}",
        f"{indent}{GO} go {NO_GO} no-go {NO_LANDING} no landing ▲ recommended ^ cursor ←/→ · {age_text}",
    ]
    return "\n".join(lines)
