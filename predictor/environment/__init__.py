"""What the capsule falls through and onto: GFS weather as one cube, and the terrain under it.

``weather`` turns GRIB files into one regional ``WeatherCube`` (``cube``), reading them with eccodes
(``gribread``, after ``gribcheck`` has scanned them); ``gfs_fetch`` and ``gfs_cache`` get and keep GFS
forecasts; ``gribwrite`` and ``demo_weather`` write GRIB2 for the demo and for tests; ``region`` sizes
the region worth decoding; ``terrain`` is the ground height under a descent.
"""

from typing import TYPE_CHECKING

from predictor.lazy_door import lazy_door

if TYPE_CHECKING:
    from .cube import WeatherCube as WeatherCube
    from .demo_weather import demo_weather_files as demo_weather_files
    from .gfs_cache import (
        SIZE_ONLY_KEEP as SIZE_ONLY_KEEP,
        PruneResult as PruneResult,
        free_space_warning as free_space_warning,
        prune as prune,
    )
    from .gfs_fetch import (
        AVAILABILITY_DELAY as AVAILABILITY_DELAY,
        DEFAULT_URL_TEMPLATE as DEFAULT_URL_TEMPLATE,
        RESOLUTIONS as RESOLUTIONS,
        URL_TEMPLATE_ENV as URL_TEMPLATE_ENV,
        Downloader as Downloader,
        Region as Region,
        plan_forecast_files as plan_forecast_files,
    )
    from .gribwrite import (
        GFS_LEVELS_HPA as GFS_LEVELS_HPA,
        gfs_file_name as gfs_file_name,
        write_gfs_grib2 as write_gfs_grib2,
    )
    from .region import weather_bbox as weather_bbox
    from .terrain import SEA_LEVEL_SOURCE as SEA_LEVEL_SOURCE, Terrain as Terrain
    from .weather import default_cache_dir as default_cache_dir, load_weather as load_weather

__getattr__, __dir__, __all__ = lazy_door(
    __name__,
    {
        "AVAILABILITY_DELAY": "gfs_fetch",
        "DEFAULT_URL_TEMPLATE": "gfs_fetch",
        "Downloader": "gfs_fetch",
        "GFS_LEVELS_HPA": "gribwrite",
        "PruneResult": "gfs_cache",
        "RESOLUTIONS": "gfs_fetch",
        "Region": "gfs_fetch",
        "SEA_LEVEL_SOURCE": "terrain",
        "SIZE_ONLY_KEEP": "gfs_cache",
        "Terrain": "terrain",
        "URL_TEMPLATE_ENV": "gfs_fetch",
        "WeatherCube": "cube",
        "default_cache_dir": "weather",
        "demo_weather_files": "demo_weather",
        "free_space_warning": "gfs_cache",
        "gfs_file_name": "gribwrite",
        "load_weather": "weather",
        "plan_forecast_files": "gfs_fetch",
        "prune": "gfs_cache",
        "weather_bbox": "region",
        "write_gfs_grib2": "gribwrite",
    },
)
