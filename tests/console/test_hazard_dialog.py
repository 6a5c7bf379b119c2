"""The FIRE/PARACHUTE dialog reads what was typed into the field it was typed for, even in a burst."""

from __future__ import annotations

import pytest
from textual import events
from textual.app import App
from textual.widgets import Button, Input

from console.screens.modals import HazardConfirmation, HazardModal
from tests.console.conftest import wait_for

pytestmark = pytest.mark.asyncio

KEY_NAMES = {"\r": "enter", " ": "space", ",": "comma", "-": "minus"}


class _DialogHost(App[None]):
    def __init__(self, override_prompt: str | None = None, second_required: bool = False) -> None:
        super().__init__()
        self.override_prompt = override_prompt
        self.second_required = second_required
        self.answers: list[HazardConfirmation | None] = []

    def on_mount(self) -> None:
        modal = HazardModal(
            "DRS1", "FIRE", "Releases DRS1.", self.second_required, override_prompt=self.override_prompt
        )
        self.push_screen(modal, self.answers.append)


def _burst(app: App[None], text: str) -> None:
    """Post every key at once, as the terminal driver does with one read of a slow link's packet.

    ``pilot.press`` waits for the app to go idle after each key, which hides the race this pins.
    """
    for char in text:
        key = KEY_NAMES.get(char, char)
        app.post_message(events.Key(key, None if key == "enter" else char))


async def test_a_burst_of_keys_fills_each_field_in_order() -> None:
    app = _DialogHost()
    async with app.run_test() as pilot:
        await wait_for(pilot, lambda: isinstance(app.screen, HazardModal))
        _burst(app, "DRS1\r\rend-to-end test, one operator\r")
        await wait_for(pilot, lambda: bool(app.answers))
    assert app.answers == [HazardConfirmation("DRS1", "", "end-to-end test, one operator", "")]


async def test_a_burst_reaches_the_override_field_when_the_dialog_has_one() -> None:
    app = _DialogHost(override_prompt="No landed evidence: override?")
    async with app.run_test() as pilot:
        await wait_for(pilot, lambda: isinstance(app.screen, HazardModal))
        _burst(app, "DRS1\rB Jones\r\rseen on the ground by the team\r")
        await wait_for(pilot, lambda: bool(app.answers))
    assert app.answers == [HazardConfirmation("DRS1", "B Jones", "", "seen on the ground by the team")]


async def test_with_another_login_required_the_dialog_offers_only_that() -> None:
    """require_second_operator refuses a typed second operator and a waiver: they are not offered, and
    the only way on is to ask another login (Enter on the name does so)."""
    app = _DialogHost(second_required=True)
    async with app.run_test(size=(80, 24)) as pilot:
        await wait_for(pilot, lambda: isinstance(app.screen, HazardModal))
        assert [i.id for i in app.screen.query(Input)] == ["typed"]
        assert [b.id for b in app.screen.query(Button)] == ["cancel", "approval"]
        _burst(app, "DRS1\r")
        await wait_for(pilot, lambda: bool(app.answers))
    assert app.answers == [HazardConfirmation("DRS1", "", "", "", await_approval=True)]
