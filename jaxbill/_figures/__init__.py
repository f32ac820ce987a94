"""What ``jaxbill figures`` computes and writes: the paper's figures, its scans, and the reduced section.

``make_figures(out_dir)`` runs every figure with built-in defaults and writes,
into ``out_dir``:

* ``fig1_trajectory.png``: Fig. 1, R = 2, ell = 1: the centre's path, the
  stick at its contacts, the rotating lens wall at one contact;
* ``fig2_projected_section.png``: Fig. 2, R = 2, ell = 1.9: one regular and
  one chaotic orbit, 1e4 collisions each, in the paper's axes (L_z against
  phi_c in units of pi);
* ``fig3_lens_section.png``: Fig. 3, I = inf, R = 2, ell = 1.5, many orbits,
  in the paper's axes and in the lens's Birkhoff coordinates;
* ``ell_scan.png``: ell = 1.9, 1.5, 1.1, 0.5, 0.1 (I = M ell^2): projected
  section above, reduced section below;
* ``inertia_scan.png``: ell = 1.9, I = M ell^2 times 1, 1/100, 1/200, the same
  two rows;
* ``fig2_reduced_vs_projected.png``: the Fig. 2 orbits in the reduced section
  (at their common E and L) beside the projection;
* ``spiral_column.png``: the Fig. 1 orbit as a point in the spiral column;
* ``walls_sections.png``: the stick between two flat walls (ell = 1,
  I = M ell^2), h = 1.5, 2.05, 2.5, 3, 4, 8: the 2D floor section
  ``(theta mod pi, p)`` (top) and the 3D reduced section at ``I w_z = 0.6
  sqrt(2 I E')`` (bottom), many orbits each, chaotic ones grey;
* ``walls_3d_flights.png``: one start point's flights in the ``(kappa theta, z)``
  plane: the 2D stick (straight), the same orbit run in 3D (``L_z = 0``:
  straight, the polar angle folded at the vertical) and a 3D stick spinning
  about the vertical (curved, kept off the vertical by ``L_z^2 / (2 I sin^2
  theta)``);
* ``ellipse.png``: the stick in an ellipse (``a = 2, b = 1.3``): one
  trajectory of a stick (``ell = 0.6``) with the stick drawn at its contacts,
  the point's Birkhoff section ``(s, p)`` (area-preserving; the elliptic
  billiard is integrable, so every orbit draws a curve) and the stick's
  ``(s, p)`` of the touching end (a projection); recorded under
  ``"ellipse"``;
* ``compositions.png``: bodies in tables (``jb.BodyInTable``): a triangle
  in a stadium, a dumbbell of masses 1:3 in an ellipse, a square in a
  circle, a point in the stadium and an elliptic coin between two walls;
  one orbit each from a Liouville start at ``E = 1/2`` (the coin's on its
  floor section, tossed sideways), the table, the centre's path and the
  body at some of its collisions; recorded under ``"compositions"``;
* ``summary.json`` and ``summary.txt``: every panel's parameters, orbit and
  collision counts, worst invariant drifts, chaotic fraction, start states
  (json), timings. The wall scenes' panels are under ``"walls"`` (not
  ``"figures"``), with their own drifts: relative energy, and the conserved
  momentum (``M vx`` in 2D, ``L_z`` in 3D) in units of ``sqrt(2 M E')`` and
  ``sqrt(2 I E')``.

All orbits of a section start on the section itself (``section_seeds`` /
``section_state``) at energy ``E = 1/2`` and total angular momentum ``L = 0``
(what a stick started at rest in its spin with its centre moving through the
origin has), so every reduced-section panel holds one ``(E, L)``. The paper
gives no initial conditions; ``L = 0`` is the choice under which its projected
section shows tori at all (orbits with ``L != 0`` precess, and their
projection smears into bands; see notebook 03).

Drifts: ``energy_drift`` is ``max |E_j / E_0 - 1|`` over all collisions ``j``
and orbits of a panel, ``E_0`` each orbit's start; ``angular_momentum_drift``
is ``max |L_j - L_0| / (R sqrt(2 M E_0))`` (``L_0`` may be 0, so the drift is
measured against the largest angular momentum the energy allows at radius R);
none for the lens, whose orbital angular momentum is not conserved. An orbit
is counted as chaotic when it and a twin started with its velocity turned by
``1e-11`` rad end up more than ``1e-3`` apart (``is_chaotic`` in
``jaxbill._analysis.section_measures``: tori give ``< 1e-6``, chaos order one); with
seeds uniform in the area-preserving ``(s, p)``, the chaotic share of seeds
estimates the chaotic share of the section. Fig. 2's orbits also get their
``curve_thickness`` (a curve: below 0.01; an area: above 0.4).

The wall scenes (``jaxbill._scenes.walls.sections``) start every orbit on the floor
section at ``E' = 1/2`` (no horizontal motion), seeds uniform in the
area-preserving ``(theta, p)``; chaotic means a twin with ``(theta_dot,
eta_dot)`` turned by ``1e-11`` rad ends up more than ``1e-3`` away;
``median_separation_collisions`` records after how many collisions the twins
are ``1e-4`` apart and ``lyapunov_per_collision`` the median ``ln(1e7) / that``
over the chaotic orbits; ``regular_island_counts`` (3D) the pieces each regular
orbit draws on a 150 x 150 grid (``count_islands``).

``quick=True`` runs the same figures with few orbits and collisions (for
tests: under half a minute).
"""

from jaxbill._figures.common import Settings
from jaxbill._figures.compositions import COMPOSITIONS_FILES, composition_scenes
from jaxbill._figures.ellipse import ELLIPSE_FILES
from jaxbill._figures.paper import invariant_drifts
from jaxbill._figures.run import FILES, Progress, make_figures, summary_text
from jaxbill._figures.walls import WALLS_FILES

__all__ = [
    "COMPOSITIONS_FILES",
    "ELLIPSE_FILES",
    "FILES",
    "WALLS_FILES",
    "Progress",
    "Settings",
    "composition_scenes",
    "invariant_drifts",
    "make_figures",
    "summary_text",
]
