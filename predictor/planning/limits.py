"""Bounds on the planner's user-sized work, in a module light enough for ``drs plan --help`` to state them.

Why bounds: ``drs predict --members 10000000`` once grew to 24 GB and was killed by the kernel, which on
an operations laptop could as well have picked the MO receiver or the console.
"""

MAX_MEMBER_DESCENTS = 2_000_000
"""Ensemble member descents in one sweep (candidates × members), all computed at once: measured at about
210 bytes each (121 candidates × 20,000 members took 510 MB above the weather), so a sweep stays under
about half a gigabyte."""
