"""Requests waiting for a second operator: approved or rejected here, from this console's own login.

The second operator of a hazardous command (Go, PARACHUTE, a take-over of release authority) is
another login, not a name typed beside the first (``drs_link.ops.approval``). Another console on the same
store shows the request as it arrives; here its operator reads what they are approving (the highlighted
request's brief, ``Approval.for_approver``, the same text `drs approve` prints: the command, the go/no-go
verdicts, every waiver with its reason and author, the landed evidence or the override's reason), then
Enter approves and ``x`` rejects with a reason. The rule is below the screen: the requester's own login is
refused, whichever console it sits at.
"""

from __future__ import annotations

from textual.app import ComposeResult
from textual.binding import Binding
from textual.widgets import DataTable, Static

from console.screens.base import ConsoleScreen
from console.screens.modals import ConfirmModal, TextPromptModal
from console.widgets import fill_rows, set_content
from drs_link.ops import ACTIONS, Approval, ApprovalBook, current_login, shown

COLUMNS = ("#", "Capsule", "Command", "Requested by", "Expires")
HELP = (
    "`↑`/`↓` a request · `Enter` approve it · `x` reject it (asks the reason) · "
    "the requester's own login is refused"
)
"""The keys, as the help screen lists them (``console.screens.registry``)."""


class ApprovalScreen(ConsoleScreen):
    BINDINGS = [
        Binding("escape", "app.pop_screen", "Back"),
        Binding("enter", "approve", "Approve"),
        Binding("x", "reject", "Reject"),
    ]

    def compose(self) -> ComposeResult:
        yield from self.compose_banner()
        yield DataTable(id="approvals", cursor_type="row")
        yield Static(id="approval-detail", markup=False)
        yield from self.compose_footer()

    def on_mount(self) -> None:
        self.you = current_login()
        """Proven once for the screen's line (an agent key proves itself by signing, which an agent loaded
        with ``ssh-add -c`` asks its owner to confirm); each decision proves it again."""
        self.ready = True
        table = self.query_one("#approvals", DataTable)
        for title in COLUMNS:
            table.add_column(title)
        table.focus()
        self.refresh_view()

    @property
    def book(self) -> ApprovalBook:
        return self.context.approval_book()

    def update_view(self) -> None:
        now = self.context.now()
        requests = self.book.open_requests()
        rows = [
            (str(r.id), (str(r.id), shown(r.capsule), f"{ACTIONS[r.action]}: {shown(r.summary)}",
                         f"{shown(r.requested_by)} ({shown(r.requester)})", f"{r.expires_utc:%H:%M:%S}Z"))
            for r in requests
        ]  # fmt: skip
        fill_rows(self.query_one("#approvals", DataTable), rows)
        chosen = self.selected()
        brief = next((r.for_approver(now) for r in requests if r.id == chosen), [])
        you = f"You are {self.you}: the requester's own login cannot approve."
        text = (
            "Nothing waits for approval."
            if not requests
            else "Enter approves the highlighted request, x rejects it."
        )
        set_content(
            self.query_one("#approval-detail", Static),
            "\n".join([*brief, text, you, f"{len(requests)} waiting at {now:%H:%M:%S}Z"]),
        )

    def on_data_table_row_highlighted(self, event: DataTable.RowHighlighted) -> None:
        """The highlighted request's brief, below the table, before Enter is pressed."""
        if getattr(self, "ready", False):
            self.refresh_view()

    def selected(self) -> int | None:
        table = self.query_one("#approvals", DataTable)
        if not table.row_count:
            return None
        return int(str(table.coordinate_to_cell_key(table.cursor_coordinate).row_key.value))

    def on_data_table_row_selected(self, event: DataTable.RowSelected) -> None:
        """Enter on a row reaches the table first: it approves, as the footer says."""
        self.action_approve()

    def action_approve(self) -> None:
        approval = self.selected()
        if approval is None:
            return
        request = self.book.get(approval)

        def confirmed(yes: bool | None) -> None:
            if yes:
                self._decide(approval, True, "")

        body = "\n".join(request.for_approver(self.context.now()))
        self.app.push_screen(ConfirmModal(f"Approve #{approval}?", body, "Approve"), confirmed)

    def action_reject(self) -> None:
        approval = self.selected()
        if approval is None:
            return

        def reason(answer: str | None) -> None:
            if answer is not None and answer.strip():
                self._decide(approval, False, answer.strip())

        self.app.push_screen(TextPromptModal(f"Reject #{approval}", "Why (the requester is told):"), reason)

    def _decide(self, approval: int, approve: bool, reason: str) -> None:
        operator, book = self.context.operator, self.book

        def shown(decided: Approval) -> None:
            self.app.notify(f"#{decided.id} {decided.state}")
            self.refresh_view()

        self.write_off_ui(
            lambda: book.decide(approval, operator, current_login(), approve, reason),
            shown,
            lambda exc: self.app.notify(str(exc), severity="error", timeout=12),
        )
