"""Analyses that ask a scene for what they need: chaos indicators, Lyapunov spectra, periodic
orbits, section measures."""
