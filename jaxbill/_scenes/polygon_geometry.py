"""Convex polygons from their vertices: checks, area, centroid, widths (numpy, on concrete vertices)."""

from __future__ import annotations

import numpy as np

from jaxbill._engine.validation import real_parameter


def checked_vertices(name: str, vertices) -> np.ndarray:
    """``vertices`` as a float64 ``(n, 2)`` array of a strictly convex polygon in anticlockwise order.

    ValueError naming ``name`` for fewer than three vertices, non-finite ones,
    repeated ones, vertices out of order (clockwise) or a polygon that is not
    convex (a reflex or a straight angle).
    """
    v = real_parameter(name, vertices)
    if v.ndim != 2 or v.shape[1] != 2 or v.shape[0] < 3:
        raise ValueError(f"{name} must be an array of shape (n, 2) with n >= 3 (the polygon's corners); got {v.shape}")
    if not np.all(np.isfinite(v)):
        raise ValueError(f"{name} must be finite")
    edges = np.roll(v, -1, axis=0) - v
    lengths = np.hypot(edges[:, 0], edges[:, 1])
    scale = float(np.max(np.abs(v - v.mean(axis=0)))) or 1.0
    if np.any(lengths <= 1e-12 * scale):
        raise ValueError(f"{name} must not repeat a corner (two consecutive vertices coincide)")
    turns = edges[:, 0] * np.roll(edges, -1, axis=0)[:, 1] - edges[:, 1] * np.roll(edges, -1, axis=0)[:, 0]
    if np.all(turns < 0):
        raise ValueError(f"{name} must go round the polygon anticlockwise; these go clockwise (reverse them)")
    if not np.all(turns > 1e-12 * scale * scale):
        bad = int(np.argmin(turns))
        raise ValueError(
            f"{name} must be the corners of a convex polygon in anticlockwise order; the corner "
            f"{(bad + 1) % len(v)} at {v[(bad + 1) % len(v)].tolist()} is reflex or straight (or out of order)"
        )
    # Anticlockwise turns at every corner may still wind twice (a star): the angles must add up to one turn.
    heading = np.unwrap(np.arctan2(edges[:, 1], edges[:, 0]))
    total = heading[-1] - heading[0] + np.arctan2(turns[-1], np.dot(edges[-1], edges[0]))
    if total > 2.0 * np.pi + 1e-9:
        raise ValueError(f"{name} wind round more than once: they are not the corners of a convex polygon")
    return v


def area_and_centroid(v: np.ndarray) -> tuple[float, np.ndarray]:
    """The area and the centroid of the uniform lamina bounded by the anticlockwise polygon ``v``."""
    nxt = np.roll(v, -1, axis=0)
    cross = v[:, 0] * nxt[:, 1] - nxt[:, 0] * v[:, 1]
    area = 0.5 * np.sum(cross)
    centroid = np.sum((v + nxt) * cross[:, None], axis=0) / (6.0 * area)
    return float(area), centroid


def lamina_polar_moment(v: np.ndarray) -> float:
    """``int |P|^2 dA`` over the polygon ``v`` (about the origin), per unit area density."""
    nxt = np.roll(v, -1, axis=0)
    cross = v[:, 0] * nxt[:, 1] - nxt[:, 0] * v[:, 1]
    square = v[:, 0] ** 2 + v[:, 0] * nxt[:, 0] + nxt[:, 0] ** 2 + v[:, 1] ** 2 + v[:, 1] * nxt[:, 1] + nxt[:, 1] ** 2
    return float(np.sum(cross * square) / 12.0)


def diameter(v: np.ndarray) -> float:
    """The largest distance between two corners."""
    difference = v[:, None, :] - v[None, :, :]
    return float(np.max(np.hypot(difference[..., 0], difference[..., 1])))


def width(v: np.ndarray) -> float:
    """The smallest width: for a convex polygon, the least over its sides of the farthest corner from its line."""
    edges = np.roll(v, -1, axis=0) - v
    normals = np.stack([edges[:, 1], -edges[:, 0]], axis=1) / np.hypot(edges[:, 0], edges[:, 1])[:, None]
    reach = np.einsum("jkd,jd->jk", v[None, :, :] - v[:, None, :], normals)
    return float(np.min(np.max(-reach, axis=1)))


def regular(n: int, radius: float, name: str = "n") -> np.ndarray:
    """The corners ``radius (cos(2 pi j / n), sin(2 pi j / n))`` of a regular ``n``-gon, anticlockwise."""
    if isinstance(n, bool) or int(n) != n or n < 3:
        raise ValueError(f"{name} must be an integer >= 3 (the number of corners); got {n!r}")
    angle = 2.0 * np.pi * np.arange(int(n)) / int(n)
    return float(radius) * np.stack([np.cos(angle), np.sin(angle)], axis=1)
