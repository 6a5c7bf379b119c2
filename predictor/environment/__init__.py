"""What the capsule falls through and onto: GFS weather as one cube, and the terrain under it.

``weather`` turns GRIB files into one regional ``WeatherCube`` (``cube``), reading them with eccodes
(``gribread``, after ``gribcheck`` has scanned them); ``gfs_fetch`` and ``gfs_cache`` get and keep GFS
forecasts; ``gribwrite`` and ``demo_weather`` write GRIB2 for the demo and for tests; ``region`` sizes
the region worth decoding; ``terrain`` is the ground height under a descent.
"""

from predictor.lazy_door import lazy_door

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
