"""The tables: convex regions built from smooth pieces."""
