"""Widgets and cell renderers shared by the console screens."""

from typing import TYPE_CHECKING

from predictor.lazy_door import lazy_door

if TYPE_CHECKING:
    from .banner import ModeBanner as ModeBanner, OverrideBanner as OverrideBanner
    from .capsule_detail import CapsuleDetail as CapsuleDetail
    from .cells import balloon_lines as balloon_lines
    from .fleet_table import FleetTable as FleetTable
    from .landing_map import LandingMap as LandingMap, MapLayers as MapLayers
    from .quiet import fill_rows as fill_rows, set_content as set_content
    from .release_timeline import default_cursor as default_cursor, render_timeline as render_timeline

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
