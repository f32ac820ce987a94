"""Two studies built on jaxbill, each with its stored data and its notebook.

* ``jaxbill.studies.small_stick``: how chaotic a short stick is, the largest
  Lyapunov exponent against the stick's length in the circle and the ellipse,
  measured over invariant ensembles and derived from a reduced kick map
  (notebook 09).
* ``jaxbill.studies.arnold_web``: the web of resonances of a stick in a
  slightly eccentric ellipse, from torus frequencies and FLI maps, and the
  diffusion of the angular momentum along it (notebook 10).

Import them by name (``from jaxbill.studies import small_stick``); the tools the
rest of jaxbill uses too (``jb.ensemble_lyapunov``, ``jb.torus_frequencies``,
``jb.resonances``) are also in the top-level namespace.
"""
