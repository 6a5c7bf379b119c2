"""Widgets and cell renderers shared by the console screens."""

from predictor.lazy_door import lazy_door

__getattr__, __dir__, __all__ = lazy_door(
    __name__,
    {
        "CapsuleDetail": "capsule_detail",
        "FleetTable": "fleet_table",
        "LandingMap": "landing_map",
        "MapLayers": "landing_map",
        "ModeBanner": "banner",
        "OverrideBanner": "banner",
        "balloon_lines": "cells",
        "default_cursor": "release_timeline",
        "fill_rows": "quiet",
        "render_timeline": "release_timeline",
        "set_content": "quiet",
    },
)
