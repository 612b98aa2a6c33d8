"""The scenarios shipped with rotorcosim (installed as the package ``rotorcosim_scenarios``).

``rotorcosim scenarios`` lists them, ``rotorcosim run quickstart`` runs one by name and
``rotorcosim init DIR`` copies them for editing (see orchestrator/shipped.py).
"""
