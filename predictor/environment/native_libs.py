"""Load order of the native libraries: PROJ (through pyproj) before eccodes.

Why: the eccodes and pyproj wheels each carry their own copy of the PROJ library. When eccodes is
loaded first, its copy's symbols win and the process crashes at exit (double free in PROJ's static
destructors, exit status 134/139 after correct output), which breaks exit codes of `drs` and pytest.
Loading pyproj first avoids it. Every module that imports eccodes or cfgrib imports this one before.
"""

import pyproj  # noqa: F401
