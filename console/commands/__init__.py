"""The ``drs`` command line: one module per command, each a thin caller of the rooms below.

``main`` is the entry point and dispatches to the command's module only; ``argparser`` and ``logs``
are what every command shares.
"""
