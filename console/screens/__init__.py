"""The console's screens. The ones the fleet opens are listed once, in ``console.screens.registry``."""
