"""A conservative sphere model of any robot, fitted to the convex shapes PyBullet collides with.

Batched collision tests see a robot as spheres in its links' frames; "no sphere touches" may
only mean "PyBullet finds no contact" if the spheres contain every link's collision shape.
Published sphere sets (cuRobo's, VAMP's) approximate their meshes and leave gaps of several
centimetres against the hulls PyBullet collides with, so the model is fitted to those hulls
(:mod:`stalm.world.link_shapes`) and then *checked*, never trusted:

1. fit: candidate centres on a grid inside each convex part; a candidate's radius is its
   depth below the part's surface plus :data:`DELTA` (it bulges at most ``DELTA`` out of the
   part). A greedy set cover picks, again and again, the candidate that covers the most
   still-uncovered points sampled on the link's surface (hull vertices included);
2. re-check on fresh surface samples and grow the link's spheres by the worst residual plus
   :data:`CONTACT_MARGIN` (PyBullet reports contacts that close), plus :data:`SLACK`;
3. :func:`check_spheres`, run on samples drawn apart from the fit's (by ``stalm robot check``
   and the tests): every sampled surface point lies at least ``CONTACT_MARGIN`` inside some
   sphere of its link. The worst residual is reported; a model that fails it is refused.

A smaller ``DELTA`` gives tighter spheres and more of them. Every random draw comes from the
Generator passed in, so a fit is reproducible.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import ConvexHull, QhullError

DELTA = 0.02
"""How far (m) a fitted sphere may bulge out of its link's convex part."""
CONTACT_MARGIN = 0.001
"""PyBullet's collision margin on convex shapes (m): the spheres cover the hull grown by it."""
SLACK = 0.001
"""Extra growth (m) beyond the re-check's residual: fresh samples may land a little farther."""
FIT_SAMPLES = 3000
"""Surface points per link the greedy cover must cover."""
RECHECK_SAMPLES = 20000
"""Fresh surface points per link the fitted spheres are grown to cover."""
CHECK_SAMPLES = 5000
"""Fresh surface points per link :func:`check_spheres` tests by default."""
GRID = 0.01
"""Candidate centres' spacing (m), coarser on a part too big for :data:`MAX_CANDIDATES`."""
MAX_CANDIDATES = 3000
"""Grid points at most per convex part."""
FLAT = 1e-6
"""How far (m) outside a part a candidate centre may lie and still count as inside it: the
mid-plane of a part without thickness, whose hull Qhull joggles."""


@dataclass(frozen=True)
class LinkSpheres:
    """One link's spheres in its URDF frame."""

    link: str
    centres: np.ndarray
    """n x 3 (m)."""
    radii: np.ndarray
    """n (m)."""


@dataclass(frozen=True)
class SphereCheck:
    """The result of :func:`check_spheres`: the largest residual (distance of a surface point
    outside its link's nearest sphere surface; negative = inside by that much) over every
    link's samples, and where it was."""

    samples: int
    worst_residual: float
    worst_link: str
    residual_by_link: dict[str, float]

    @property
    def passed(self) -> bool:
        """Every sampled point lies at least :data:`CONTACT_MARGIN` inside a sphere."""
        return self.worst_residual <= -CONTACT_MARGIN


@dataclass(frozen=True)
class _Part:
    points: np.ndarray
    equations: np.ndarray
    """Outward face planes (normal, offset): a point x is inside when n . x + offset <= 0."""
    triangles: np.ndarray
    """Surface triangles, t x 3 x 3."""


def _part(points: np.ndarray) -> _Part:
    try:
        hull = ConvexHull(points)
    except QhullError:  # a flat part (a plate modelled without thickness): joggle it
        hull = ConvexHull(points, qhull_options="QJ")
    return _Part(points[hull.vertices], hull.equations, points[hull.simplices])


def _surface_samples(parts: list[_Part], count: int, rng: np.random.Generator) -> np.ndarray:
    """``count`` points uniform on the parts' hull surfaces (by area), then their vertices."""
    triangles = np.concatenate([part.triangles for part in parts])
    edges_a = triangles[:, 1] - triangles[:, 0]
    edges_b = triangles[:, 2] - triangles[:, 0]
    area = 0.5 * np.linalg.norm(np.cross(edges_a, edges_b), axis=1)
    chosen = rng.choice(len(triangles), size=count, p=area / area.sum())
    u, v = rng.random(count), rng.random(count)
    flip = u + v > 1.0
    u[flip], v[flip] = 1.0 - u[flip], 1.0 - v[flip]
    points = triangles[chosen, 0] + u[:, None] * edges_a[chosen] + v[:, None] * edges_b[chosen]
    return np.concatenate([points, *(part.points for part in parts)])


def _depth(part: _Part, points: np.ndarray) -> np.ndarray:
    """Distance of each point below the part's surface (negative outside)."""
    return np.asarray(-(points @ part.equations[:, :3].T + part.equations[:, 3]).max(axis=1))


def _candidates(part: _Part, delta: float) -> tuple[np.ndarray, np.ndarray]:
    low, high = part.points.min(axis=0), part.points.max(axis=0)
    volume = float(np.prod(np.maximum(high - low, GRID)))
    step = max(GRID, (volume / MAX_CANDIDATES) ** (1.0 / 3.0))
    axes = [
        np.arange(a + step / 2, b, step) if b - a > step else np.array([(a + b) / 2])
        for a, b in zip(low, high, strict=True)
    ]  # a part thinner than a step gets its mid-plane
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    centres = np.concatenate([grid, part.points.mean(axis=0, keepdims=True)])
    depth = _depth(part, centres)
    inside = depth >= -FLAT  # a flat part's mid-plane lies on its (joggled) hull
    return centres[inside], np.maximum(depth[inside], 0.0) + delta


def _residuals(points: np.ndarray, centres: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """Per point: how far outside the nearest sphere surface it lies (negative = inside)."""
    worst = np.full(len(points), np.inf)
    for start in range(0, len(centres), 256):
        block = slice(start, start + 256)
        gaps = np.linalg.norm(points[:, None, :] - centres[None, block], axis=2) - radii[block]
        worst = np.minimum(worst, gaps.min(axis=1))
    return worst


def _greedy_cover(
    samples: np.ndarray, centres: np.ndarray, radii: np.ndarray, delta: float
) -> tuple[np.ndarray, np.ndarray]:
    covers = np.zeros((len(samples), len(centres)), dtype=bool)
    for start in range(0, len(centres), 256):
        block = slice(start, start + 256)
        gaps = np.linalg.norm(samples[:, None, :] - centres[None, block], axis=2)
        covers[:, block] = gaps <= radii[block]
    uncovered = np.ones(len(samples), dtype=bool)
    counts = covers.sum(axis=0)
    chosen: list[int] = []
    while counts.size and counts.max() > 0:
        best = int(counts.argmax())
        chosen.append(best)
        newly = covers[:, best] & uncovered
        uncovered &= ~newly
        counts -= covers[newly].sum(axis=0)
    picked_centres = [centres[chosen]]
    picked_radii = [radii[chosen]]
    if uncovered.any():  # points no candidate reaches (a sliver of a part): spheres on them
        left = samples[uncovered]
        extra = _greedy_cover(left, left, np.full(len(left), delta), delta)
        picked_centres.append(extra[0])
        picked_radii.append(extra[1])
    return np.concatenate(picked_centres), np.concatenate(picked_radii)


def fit_link_spheres(
    link: str, points: list[np.ndarray], rng: np.random.Generator, delta: float = DELTA
) -> LinkSpheres:
    """Spheres covering the convex hulls of ``points`` (one array per convex part, link frame)."""
    parts = [_part(np.asarray(part, dtype=float)) for part in points]
    found = [_candidates(part, delta) for part in parts]
    centres = np.concatenate([pair[0] for pair in found])
    radii = np.concatenate([pair[1] for pair in found])
    samples = _surface_samples(parts, FIT_SAMPLES, rng)
    centres, radii = _greedy_cover(samples, centres, radii, delta)
    fresh = _surface_samples(parts, RECHECK_SAMPLES, rng)
    growth = max(float(_residuals(fresh, centres, radii).max()), 0.0)
    return LinkSpheres(link, centres, radii + growth + CONTACT_MARGIN + SLACK)


def check_spheres(
    parts_by_link: dict[str, list[np.ndarray]],
    spheres: dict[str, LinkSpheres],
    rng: np.random.Generator,
    samples: int = CHECK_SAMPLES,
) -> SphereCheck:
    """Sample ``samples`` points on each link's hull surfaces (plus the hull vertices) and
    measure how far the worst lies outside that link's spheres (see :class:`SphereCheck`).
    A link with collision geometry but no spheres fails outright (infinite residual)."""
    residuals: dict[str, float] = {}
    total = 0
    for link, points in parts_by_link.items():
        parts = [_part(np.asarray(part, dtype=float)) for part in points]
        surface = _surface_samples(parts, samples, rng)
        total += len(surface)
        model = spheres.get(link)
        if model is None or len(model.radii) == 0:
            residuals[link] = float("inf")
            continue
        residuals[link] = float(_residuals(surface, model.centres, model.radii).max())
    worst_link = max(residuals, key=lambda name: residuals[name])
    return SphereCheck(total, residuals[worst_link], worst_link, residuals)
