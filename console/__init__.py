"""The operator console: the Textual app and the `drs` command line."""
