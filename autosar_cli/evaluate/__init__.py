"""Evaluation: a focused run against the simulator's truth (``autosar evaluate``), and methods side by side
(``compare``)."""
