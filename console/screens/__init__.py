"""The console's screens. The ones the fleet opens are listed once, in ``console.screens.registry``."""

from typing import TYPE_CHECKING

from predictor.lazy_door import lazy_door

if TYPE_CHECKING:
    from .fleet import FleetScreen as FleetScreen
    from .help import HelpScreen as HelpScreen
    from .modals import ConfirmModal as ConfirmModal
    from .registry import palette_commands as palette_commands

__getattr__, __dir__, __all__ = lazy_door(
    __name__,
    {
        "ConfirmModal": "modals",
        "FleetScreen": "fleet",
        "HelpScreen": "help",
        "palette_commands": "registry",
    },
)
