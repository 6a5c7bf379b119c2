"""Calibration inputs: measured flight tracks, the rules that clean them, and the winds of their ascents.

The calibration loop (residuals, effects, selection) and live re-prediction build on three things
from here: ``tracks`` reads every track format into one ``Track`` of ``Fix`` es, ``cleaning`` turns a
track into a ``Flight`` (ascent, descent, landing, and why anything was dropped or why the flight
cannot be used), and ``ascent_winds`` turns a flight's own ascent into a ``WeatherCube`` so that a
real descent can be predicted with no forecast at all.
"""
