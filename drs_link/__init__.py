"""Talking to capsules: SSH to the Pi before release, Iridium SBD after, and the durable store.

No Textual import may appear in this package: the console renders what these services report.
"""
