"""The console's screens. The ones the fleet opens are listed once, in ``console.screens.registry``."""

from predictor.lazy_door import lazy_door

__getattr__, __dir__, __all__ = lazy_door(
    __name__,
    {
        "ConfirmModal": "modals",
        "FleetScreen": "fleet",
        "HelpScreen": "help",
        "palette_commands": "registry",
    },
)
