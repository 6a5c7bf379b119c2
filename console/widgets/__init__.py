"""Widgets and cell renderers shared by the console screens."""
