"""Iridium SBD ground side: commands to a capsule through RockBLOCK and its position reports back.

Nothing here imports Textual; the console renders what these services report.
"""
