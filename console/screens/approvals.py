"""Requests waiting for a second operator: approved or rejected here, from this console's own login.

The second operator of a hazardous command (Go, PARACHUTE, a take-over of release authority) is
another login, not a name typed beside the first (``drs_link.ops.approval``). Another console on the same
store shows the request as it arrives; here its operator reads what they are approving (the highlighted
request's brief, ``Approval.for_approver``, the same text `drs approve` prints: the command, the go/no-go
verdicts, every waiver with its reason and author, the landed evidence or the override's reason), then
Enter approves and ``x`` rejects with a reason. The requests come from the operations server's push, and
the decision goes to it (``CommandingContext.decide``): the rule is below the screen, in the server, which
knows this console's account from the kernel and refuses the requester's own, whichever console it sits at.
"""

from __future__ import annotations

from textual.app import ComposeResult
from textual.binding import Binding
from textual.widgets import DataTable, Static

from console.screens.base import ConsoleScreen
from console.screens.modals import ConfirmModal, TextPromptModal
from console.widgets import fill_rows, set_content
from drs_link.ops import ACTIONS, shown
from drs_link.server import ApprovalView

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
        self.you = self.context.account()
        """The account the server knows this console by (the kernel's word, not the console's)."""
        self.ready = True
        table = self.query_one("#approvals", DataTable)
        for title in COLUMNS:
            table.add_column(title)
        table.focus()
        self.refresh_view()

    def update_view(self) -> None:
        now = self.context.now()
        requests = self.context.open_approvals()
        rows = [
            (str(r.id), (str(r.id), shown(r.capsule), f"{ACTIONS.get(r.action, r.action)}: {shown(r.summary)}",
                         f"{shown(r.requested_by)} ({shown(r.requester_account)})",
                         f"{r.expires:%H:%M:%S}Z" if r.expires else r.expires_utc))
            for r in requests
        ]  # fmt: skip
        fill_rows(self.query_one("#approvals", DataTable), rows)
        chosen = self.selected()
        brief = next((r.described.splitlines() for r in requests if r.id == chosen), [])
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
        request = next((r for r in self.context.open_approvals() if r.id == approval), None)
        if request is None:
            return

        def confirmed(yes: bool | None) -> None:
            if yes:
                self._decide(approval, True, "")

        body = request.described
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
        context = self.context

        def shown(decided: ApprovalView) -> None:
            self.app.notify(f"#{decided.id} {decided.state}")
            self.refresh_view()

        self.write_off_ui(
            lambda: context.decide(approval, approve, reason),
            shown,
            lambda exc: self.app.notify(str(exc), severity="error", timeout=12),
        )
