#pragma once
// A wall grown from a closed surface: vertex normals (area-weighted, smoothed) to offset it along, and the prism
// mesh between the surface and its offset (each triangle `layers` prisms, each prism 3 tets).
#include <vector>

#include "physics/mesh.hpp"

namespace lumen::physics {

// Unit vertex normals of a closed, outward-oriented surface: the sum of the incident triangles' area vectors
// ((b - a) x (c - a)), normalised (a vertex whose sum is zero keeps a zero normal).
Points vertex_normals(const Points& x, const Tris& tris);

// Vertex normals smoothed over the surface: `rounds` times, each normal replaced by the normalised sum of itself
// and its edge neighbours' normals (so a normal turns toward its neighbourhood's mean direction across creases).
Points smooth_normals(const Points& normals, const Tris& tris, int rounds);

// The wall between a closed surface's two offsets, inner (layer 0) and outer (layer `layers`), on the same
// triangles (oriented so their normals point from inner toward outer): node of vertex v at layer k is
// k * n_vertices + v, at inner + (outer - inner) k / layers. Every triangle makes `layers` prisms; each prism
// (a, b, c bottom, a', b', c' top, a < b < c by vertex id) is split into the tets (a, b, c, c'), (a, b, c', b'),
// (a, a', b', c') (swapping the first two when (a, b, c) runs against the triangle): each side quad's diagonal runs from its lower
// vertex of smaller id to the upper vertex of larger id, so the prisms on either side of an edge cut it the same
// way (conforming). Surfaces: kInnerWall (layer 0, reversed: normals out of the wall), kOuterWall (the last layer,
// as given), kEndCaps (empty: the wall is closed); no node sets. Throws std::invalid_argument when the arrays
// disagree in size, layers < 1, or a triangle names a vertex out of range.
TetMesh make_prism_wall(const Points& inner, const Points& outer, const Tris& tris, int layers);

}  // namespace lumen::physics
