"""Release planning: where the balloon goes next, and which release times land well (issue 7).

``balloon`` carries the balloon forward at float altitude (or along an altitude plan), ``batch`` runs
thousands of descents from different times and places in one compiled call, ``sweep`` turns them into
per-candidate landings, zone probabilities, target distances and go/no-go with ranked windows, and
``strip`` writes the landing strip as KML/GeoJSON. Live re-prediction during a descent is in
``predictor.live``; its evaluation on real flights is ``live_evaluation``.
"""
